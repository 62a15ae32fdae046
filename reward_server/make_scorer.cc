#include "reward_server/make_scorer.h"

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "common/base/status_macros.h"
#include "reward_server/credit/registry.h"
#include "reward_server/novelty/registry.h"

namespace imca::reward {

std::vector<std::string> RewardKinds() { return Novelties().Names(); }

ScorerConfig DefaultScorerConfig(const std::string& kind, absl::string_view scenario) {
  ScorerConfig config;
  if (absl::StatusOr<const NoveltyEntry*> entry = Novelties().Find(kind); entry.ok()) (*entry)->defaults(&config);
  config.beta *= env::TuningOf(scenario).bonus_scale.value_or(1.0);
  return config;
}

absl::StatusOr<std::unique_ptr<Novelty>> MakeNovelty(const std::string& kind, const env::Scenario& scenario,
                                                     const ScorerConfig& config, const std::any& options) {
  absl::StatusOr<const NoveltyEntry*> entry = Novelties().Find(kind);
  if (!entry.ok()) return entry.status();
  return (*entry)->create(scenario, config, options);
}

std::vector<std::string> ServedCredits(const Novelty& novelty) {
  std::vector<std::string> served;
  for (const CreditRuleEntry& rule : CreditRules().entries()) {
    if (rule.reads == NoveltyReads::kNothing || novelty.Supports(rule.reads)) served.push_back(rule.name);
  }
  return served;
}

absl::StatusOr<std::unique_ptr<CreditScorer>> MakeScorer(const std::string& kind, const env::Scenario& scenario,
                                                         const ScorerConfig& config, const std::any& options) {
  if (!(config.beta >= 0)) return absl::InvalidArgumentError("beta must be >= 0");
  if (!(config.temperature > 0)) return absl::InvalidArgumentError("temperature must be > 0");
  IMCA_ASSIGN_OR_RETURN(const NoveltyReads reads, CreditReads(config.credit));
  IMCA_ASSIGN_OR_RETURN(std::unique_ptr<Novelty> novelty, MakeNovelty(kind, scenario, config, options));
  if (reads != NoveltyReads::kNothing && !novelty->Supports(reads)) {
    return absl::InvalidArgumentError(absl::StrCat("credit '", config.credit, "' is not served by reward '", kind,
                                                   "' (it serves: ", absl::StrJoin(ServedCredits(*novelty), ", "),
                                                   ")"));
  }
  return std::make_unique<CreditScorer>(std::move(novelty), config, scenario.num_agents());
}

}  // namespace imca::reward
