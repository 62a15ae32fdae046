#ifndef IMCA_REWARD_SERVER_NOVELTY_INFLUENCE_NOVELTY_H_
#define IMCA_REWARD_SERVER_NOVELTY_INFLUENCE_NOVELTY_H_

#include <string>

#include "common/env/env.h"
#include "reward_server/credit.h"
#include "reward_server/novelty/counted_novelty.h"
#include "reward_server/novelty/novelty.h"

namespace imca::reward {

// EITI and EDTI (Wang et al. 2020) from the count tables of the released
// code (EDTI's baselines/Curiosity.py; docs/baselines.md), on the agents' cells only:
// for every ordered pair (i influences j),
//   c_{i->j} = 1 - p(s'_j | s_j, a_j) / p(s'_j | s_i, a_i, s_j, a_j)
// (or, with log_form, log p(s'_j | s_i, a_i, s_j, a_j) - log p(s'_j | s_j, a_j)),
// each p a ratio of counts N(s_j, a_j, s'_j) / N(s_j, a_j) and
// N(s_i, a_i, s_j, a_j, s'_j) / N(s_i, a_i, s_j, a_j). Per time step of a
// request, all its envs' transitions are added before any is read, and a
// transition out of a reset state (t = 0) neither enters the influence tables
// nor gets an influence term, as EDTI's vec env does. The decentralised
// curiosity eta / sqrt(N_i(s'_i) + 1) reads agent i's cell count before the
// step's increments and counts every transition. Permutation modes do not
// apply (EDTI has none; the config's permutation is ignored).
// Local novelty (credit independent only; the per-agent bonus is the method):
//   eiti: eta / sqrt(N_i(s'_i) + 1) + beta_t * sum_{j != i} c_{i->j};
//   edti: eta / sqrt(N_i(s'_i) + 1), with every c_{i->j} returned as
//         influences for the learner's value-of-interaction term.
struct InfluenceConfig {
  bool edti = false;       // false: EITI.
  double eta = 10.0;       // Curiosity coefficient (EDTI's README: gamma_dec = 10 with success +1000).
  double beta_t = 10.0;    // EITI's coefficient of the summed influence (not published; docs/baselines.md).
  bool log_form = false;   // The paper's log ratio instead of the released code's 1 - 1/x.
};

// EITI's and EDTI's settings (common/base/settings.h): type, flag, field of
// InfluenceConfig (its `edti` is the kind's), help.
#define IMCA_INFLUENCE_SETTINGS(X)                                                                                  \
  X(double, eta, eta, "eiti, edti: coefficient of the decentralised curiosity eta / sqrt(N_i(s_i) + 1)")            \
  X(double, beta_t, beta_t, "eiti: coefficient of the summed influence c_{i->j}")                                   \
  X(bool, influence_log, log_form,                                                                                  \
    "eiti, edti: influence as the paper's log ratio instead of the released code's 1 - 1/x")

// The EITI/EDTI novelty above. Not thread-safe (Novelty): its CreditScorer
// serialises calls.
class InfluenceNovelty final : public CountedNovelty {
 public:
  InfluenceNovelty(const env::Scenario& scenario, const ScorerConfig& config, const InfluenceConfig& influence);

  bool Supports(NoveltyReads reads) const override { return reads == NoveltyReads::kLocal; }
  bool ReturnsInfluences() const override { return influence_.edti; }
  absl::Status Compute(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out) override;
  void FillStats(v1::RewardStats* stats) const override;

 private:
  float Influence(const int32_t* state, const int32_t* actions, const int32_t* next, int i, int j,
                  const absl::flat_hash_map<uint64_t, uint32_t>& pending) const;
  std::string ConfigTag() const override;

  const std::string scenario_tag_;
  const int n_;
  const int k_;
  const int step_index_;  // Of the step count in a state: 0 marks a reset state.
  const InfluenceConfig influence_;

  static constexpr int kTransitions = 0;  // The four tables of every pair, by key tag.
  static constexpr int kCells = 1;        // N_i(s_i) of the curiosity.
};

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_NOVELTY_INFLUENCE_NOVELTY_H_
