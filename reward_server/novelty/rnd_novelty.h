#ifndef IMCA_REWARD_SERVER_NOVELTY_RND_NOVELTY_H_
#define IMCA_REWARD_SERVER_NOVELTY_RND_NOVELTY_H_

#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "common/env/env.h"
#include "reward_server/credit.h"
#include "reward_server/novelty/learned_novelty.h"

namespace imca::reward {

struct RndConfig {
  std::vector<int> hidden = {128, 128};  // Hidden widths of target and predictor; {} = one linear layer.
  int output = 64;                       // Embedding size.
  double learning_rate = 1e-3;           // Adam, predictor only.
  double update_proportion = 1.0;        // Share of each batch's transitions the predictor trains on.
  double gamma = 0.99;                   // Discount of the intrinsic return whose running std divides N.
  bool normalize = true;                 // Input mean/std (clip +-5) and bonus normalisation.
  // Threads of imca's counterfactual rows (the Score call's and one started
  // per further thread); in a synchronous run the other cores idle while the
  // actors wait for Score. Values do not depend on it.
  int counterfactual_threads = 2;
};

// RND's settings (common/base/settings.h): type, flag, field of RndConfig, help.
#define IMCA_RND_SETTINGS(X)                                                                                        \
  X(double, rnd_lr, learning_rate, "rnd: Adam learning rate of the predictor")                                      \
  X(double, rnd_update_proportion, update_proportion, "rnd: share of each request's transitions the predictor "    \
    "trains on")                                                                                                    \
  X(int, rnd_counterfactual_threads, counterfactual_threads,                                                        \
    "rnd with imca credit: threads of the counterfactual rows (values do not depend on it)")

// Random network distillation (paper eq. 6; docs/credit.md) on the encoded joint
// state + one-hot joint action (JointInputEncoder), for CreditScorer
// (docs/credit.md):
//   N(x) = mean((f(x') - f^(x'))^2), x' = clip((x - mean) / std, -5, 5),
//   then divided by the running std of the discounted intrinsic return
//   (per env stream of each request, gamma), so that tau means the same as
//   for counts. imca contributions: r^a = N(S,U) - sum_u' pi^a(u') N(S,(U^-a,u'))
//   with all n*|A| counterfactual inputs of a batch in one forward pass (scale
//   1); local (independent): a second RND over each agent's (cell, action[, id]).
// A request is scored with the predictor as it was before the request, then
// the predictor takes one Adam step on the request's (S,U) inputs (a random
// `update_proportion` of them; under permutation random, on a random slot
// order of each). Not thread-safe (Novelty).
class RndNovelty final : public LearnedNovelty {
 public:
  // Errors: INVALID_ARGUMENT for bad config values.
  static absl::StatusOr<std::unique_ptr<RndNovelty>> Create(const env::Scenario& scenario,
                                                            const ScorerConfig& config,
                                                            const RndConfig& rnd);
  ~RndNovelty() override;

  void FillStats(v1::RewardStats* stats) const override;
  absl::Status Load(const std::string& path) override;

  // Tests: sets layer `layer` of net "target" or "predictor" (the joint
  // model; "local_target"/"local_predictor" for independent credit) to the
  // row-major weight [out][in] and bias [out]. INVALID_ARGUMENT on a shape
  // mismatch or unknown name.
  absl::Status SetLinearForTest(const std::string& net, int layer, const std::vector<float>& weight,
                                const std::vector<float>& bias);

 private:
  void ComputeJoint(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out,
                    Deferred* deferred) override;
  void ComputeLocal(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out,
                    Deferred* deferred) override;
  absl::StatusOr<std::string> Serialize() const override;

  struct Impl;
  RndNovelty(std::unique_ptr<Impl> impl, NoveltyReads reads);
  std::unique_ptr<Impl> impl_;
};

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_NOVELTY_RND_NOVELTY_H_
