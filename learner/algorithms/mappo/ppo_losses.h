#ifndef IMCA_LEARNER_ALGORITHMS_MAPPO_PPO_LOSSES_H_
#define IMCA_LEARNER_ALGORITHMS_MAPPO_PPO_LOSSES_H_

// LibTorch-only (as common/nn/mlp.h): for ppo_trainer.cc and its test.
#include <torch/torch.h>

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "common/nn/running_moments.h"
#include "learner/algorithms/mappo/ppo_trainer.h"

namespace imca::learner::internal {

// PPO's losses and the batch's normalisations, each alone so that tests can
// work them by hand. Pure.

// The PPO clipped surrogate as a loss to minimise:
//   -mean(min(ratio * A, clamp(ratio, 1 - clip, 1 + clip) * A)),
//   ratio = exp(log_probs - behaviour_log_probs).
// Outside the clip range on the side the advantage pushes towards, the min
// selects the clamped (constant) term, so such samples give no gradient.
torch::Tensor ClippedSurrogateLoss(const torch::Tensor& log_probs, const torch::Tensor& behaviour_log_probs,
                                   const torch::Tensor& advantages, double clip);

// Decoupled PPO (Hilton et al. 2021): the clip is measured against the
// proximal policy, the behaviour policy enters only as the importance weight
//   -mean(w * min(r A, clamp(r, 1 - clip, 1 + clip) A)),
//   r = exp(log_probs - proximal), w = exp(proximal - behaviour).
// `proximal` and `behaviour` carry no gradient. With proximal == behaviour
// (w = 1) it is the textbook surrogate, ClippedSurrogateLoss. Both
// log-ratios are clamped to [-kMaxLogRatio, kMaxLogRatio] before the exp, as
// IMPALA's V-trace truncates its importance weights: whatever
// log-probability an unroll carries, the ratio stays finite (at most e^10 =
// 22026). PPO's own ratios stay within a few tenths of 0, where the clamp
// does nothing; a sample beyond it gives no gradient through the ratio.
inline constexpr double kMaxLogRatio = 10.0;
torch::Tensor DecoupledSurrogateLoss(const torch::Tensor& log_probs, const torch::Tensor& proximal_log_probs,
                                     const torch::Tensor& behaviour_log_probs, const torch::Tensor& advantages,
                                     double clip);

// Mean of (w - 1) - log w over samples, w = exp(log_probs - behaviour).
double BehaviourKl(const torch::Tensor& log_probs, const torch::Tensor& behaviour_log_probs);

// A float32 tensor of `shape` holding a copy of `v`.
torch::Tensor CopyFloats(const std::vector<float>& v, std::vector<int64_t> shape);

// Mean 0, std 1 (population std), in float64 for the statistics.
torch::Tensor NormaliseAdvantages(const torch::Tensor& advantages);

// Floor on the return normaliser's variance (std >= 0.01) with
// ValueNorm::kBatch. Constant returns (e.g. a sparse reward never seen yet)
// drive the variance to 0; dividing the value targets by a vanishing std
// would blow up tiny differences.
inline constexpr double kMinReturnVar = 1e-4;
// ValueNorm::kEma's constants, on-policy's: the averages' decay per update,
// the floor of the debiasing term, the floor of the variance (std >= 0.1).
inline constexpr double kEmaBeta = 0.99999;
inline constexpr double kEmaMinDebias = 1e-5;
inline constexpr double kEmaMinVar = 1e-2;

// One value head's return normaliser (ValueNorm). Update merges returns (a
// whole batch with kBatch, a minibatch with kEma); Normalise and the
// mean/std pair map between returns and the critic's outputs. Not
// thread-safe.
class ReturnNormaliser {
 public:
  explicit ReturnNormaliser(ValueNorm kind = ValueNorm::kBatch) : kind_(kind) {}

  ValueNorm kind() const { return kind_; }
  void Update(const torch::Tensor& returns);  // [rows], any float type.
  double mean() const;
  double std() const;
  // (returns - mean) / std, float32.
  torch::Tensor Normalise(const torch::Tensor& returns) const;

  // float64 [3]: kBatch [mean, var, count], kEma [mean, mean square,
  // debiasing term] (undebiased averages).
  torch::Tensor ToTensor() const;
  // Errors: INVALID_ARGUMENT naming `name` if the tensor is not [3] or its
  // values are not a state of `kind` (non-finite, a negative variance or
  // mean square, a count <= 0, a debiasing term outside [0, 1]).
  static absl::StatusOr<ReturnNormaliser> FromTensor(ValueNorm kind, const torch::Tensor& t,
                                                     const std::string& name);

 private:
  ValueNorm kind_;
  nn::RunningMoments moments_;                           // kBatch
  double ema_mean_ = 0, ema_mean_sq_ = 0, ema_debias_ = 0;  // kEma
};

}  // namespace imca::learner::internal

#endif  // IMCA_LEARNER_ALGORITHMS_MAPPO_PPO_LOSSES_H_
