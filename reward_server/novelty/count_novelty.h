#ifndef IMCA_REWARD_SERVER_NOVELTY_COUNT_NOVELTY_H_
#define IMCA_REWARD_SERVER_NOVELTY_COUNT_NOVELTY_H_

#include <string>
#include <vector>

#include "common/base/rng.h"
#include "common/env/env.h"
#include "reward_server/credit.h"
#include "reward_server/novelty/counted_novelty.h"
#include "reward_server/novelty/joint_key.h"
#include "reward_server/novelty/novelty.h"

namespace imca::reward {

// Count-based novelty N(x) = 1 / sqrt(C_before(x) + 1) (docs/credit.md;
// docs/credit.md works an example), for CreditScorer:
//   joint (shared, imca): N(S, U) from the joint table;
//   imca contributions:   r^a = N(S,U) - sum_u' pi^a(u') N(S, (U^-a, u')),
//                         every counterfactual read before this
//                         transition's increment (scale 1);
//   local (independent):  N_a(s^a, u^a) from per-agent tables.
// Transitions are read and then counted one at a time, in order.
// Permutation modes map keys: canonical sorts the agents' pairs by cell for
// every lookup and increment; random increments the key of a random
// permutation of the pairs (lookups use agent order), as the paper's 4.3.
// For independent credit, permutation other than off makes homogeneous agents
// share one local table. Not thread-safe: its CreditScorer serialises calls.
class CountNovelty final : public CountedNovelty {
 public:
  CountNovelty(const env::Scenario& scenario, const ScorerConfig& config);

  bool Supports(NoveltyReads reads) const override { return true; }
  absl::Status Compute(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out) override;
  void FillStats(v1::RewardStats* stats) const override;

  // Current count of the joint pair (state, actions) under this scorer's key
  // mapping (canonical order if configured, agent order otherwise).
  uint32_t JointCount(const int32_t* state, const int32_t* actions) const;

 private:
  void ComputeOne(const int32_t* state, const int32_t* actions, const float* probs, bool dry_run,
                  const NoveltyOutput& out, int64_t i, Rng& rng);
  std::string ConfigTag() const override;

  const std::string scenario_tag_;  // Scenario name and map size, for snapshots.
  const int n_;
  const int num_actions_;
  const int k_;  // state_size
  const ScorerConfig config_;
  const JointKeyCodec codec_;

  static constexpr int kGlobal = 0;  // The joint table.
  static constexpr int kLocal = 1;   // The per-agent tables (one key space).
  Rng rng_;  // The random permutations (a call's own stream when deterministic).
};

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_NOVELTY_COUNT_NOVELTY_H_
