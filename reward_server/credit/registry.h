#ifndef IMCA_REWARD_SERVER_CREDIT_REGISTRY_H_
#define IMCA_REWARD_SERVER_CREDIT_REGISTRY_H_

#include <cstdint>
#include <functional>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "common/base/registry.h"
#include "reward_server/scorer.h"

namespace imca::reward {

// What a credit rule reads of a novelty kind (novelty.h's NoveltyOutput):
// nothing; each agent's local novelty N_a; the global novelty N(S, U); or
// the global novelty with each agent's counterfactual contribution r^a and
// the kind's per-agent divisor. A kind serves the rules whose reads it
// computes (Novelty::Supports); the learned kinds build the model the reads
// need (a local one for kLocal, else a joint one).
enum class NoveltyReads { kNothing, kLocal, kGlobal, kContributions };

// One batch's novelties, those the rule reads (the others null), rows of n
// agents.
struct CreditInput {
  int64_t size = 0;
  int n = 0;
  double beta = 0;         // ScorerConfig::beta.
  double temperature = 1;  // ScorerConfig::temperature.
  const float* global = nullptr;         // [size], N(S, U): kGlobal, kContributions.
  const float* local = nullptr;          // [size][n], N_a: kLocal.
  const float* contributions = nullptr;  // [size][n], r^a: kContributions.
  const double* divisor = nullptr;       // [size][n]: kContributions (1 but SF's episodic sqrt(N_ep)).
};

// A credit rule, registered in its own file beside this one (imca.cc, ...)
// by one line of rules.def, the one place that names them all.
struct CreditRuleEntry {
  std::string name;  // --credit.
  std::string help;  // One line: what each agent receives (--list).
  NoveltyReads reads = NoveltyReads::kNothing;
  // Writes R_i (out.global_rewards), r_i^a (out.agent_rewards) and p^a
  // (out.shares) of every row; out.contributions holds the kind's local
  // novelties (kLocal) or contributions (kContributions) and is the rule's
  // to zero otherwise. Called with the scorer's lock held; pure.
  std::function<void(const CreditInput& in, const ScoreOutput& out)> apply;

  bool complete() const { return static_cast<bool>(apply); }
};

// The registry (common/base/registry.h): Find's errors name --credit.
class CreditRuleRegistry : public Registry<CreditRuleEntry> {
 public:
  CreditRuleRegistry() : Registry("--credit") {}
};

// Every credit rule of rules.def, built on first use.
const CreditRuleRegistry& CreditRules();

// What rule `name` reads. Errors: INVALID_ARGUMENT naming --credit and the
// rules for an unknown name.
absl::StatusOr<NoveltyReads> CreditReads(absl::string_view name);

// p^a = softmax_a(r^a / tau) over n contributions (numerically stable).
void SoftmaxShares(const float* contributions, int n, double temperature, float* shares);

// Each file's registration, one per line of rules.def.
#define IMCA_CREDIT_RULE(Prefix) absl::Status Register##Prefix(CreditRuleRegistry* registry);
#include "reward_server/credit/rules.def"
#undef IMCA_CREDIT_RULE

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_CREDIT_REGISTRY_H_
