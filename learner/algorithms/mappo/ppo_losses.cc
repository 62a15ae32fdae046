#include "learner/algorithms/mappo/ppo_losses.h"

#include <algorithm>
#include <cmath>

namespace imca::learner::internal {
namespace {

constexpr double kAdvantageEps = 1e-8;

}  // namespace

torch::Tensor DecoupledSurrogateLoss(const torch::Tensor& log_probs,
                                     const torch::Tensor& proximal_log_probs,
                                     const torch::Tensor& behaviour_log_probs,
                                     const torch::Tensor& advantages, double clip) {
  const torch::Tensor ratio = torch::exp(torch::clamp(log_probs - proximal_log_probs, -kMaxLogRatio, kMaxLogRatio));
  const torch::Tensor unclipped = ratio * advantages;
  const torch::Tensor clipped = torch::clamp(ratio, 1.0 - clip, 1.0 + clip) * advantages;
  const torch::Tensor weight =
      torch::exp(torch::clamp(proximal_log_probs - behaviour_log_probs, -kMaxLogRatio, kMaxLogRatio));
  return -(weight * torch::min(unclipped, clipped)).mean();
}

torch::Tensor ClippedSurrogateLoss(const torch::Tensor& log_probs,
                                   const torch::Tensor& behaviour_log_probs,
                                   const torch::Tensor& advantages, double clip) {
  return DecoupledSurrogateLoss(log_probs, behaviour_log_probs, behaviour_log_probs, advantages, clip);
}

double BehaviourKl(const torch::Tensor& log_probs, const torch::Tensor& behaviour_log_probs) {
  const torch::Tensor log_w = log_probs - behaviour_log_probs;
  return ((log_w.exp() - 1.0) - log_w).to(torch::kFloat64).mean().item<double>();
}

torch::Tensor CopyFloats(const std::vector<float>& v, std::vector<int64_t> shape) {
  return torch::from_blob(const_cast<float*>(v.data()), shape, torch::kFloat32).clone();
}

torch::Tensor NormaliseAdvantages(const torch::Tensor& advantages) {
  const torch::Tensor a = advantages.to(torch::kFloat64);
  const torch::Tensor centred = a - a.mean();
  const torch::Tensor std = centred.pow(2).mean().sqrt();
  return (centred / (std + kAdvantageEps)).to(torch::kFloat32);
}

torch::Tensor NormaliseReturns(const std::vector<float>& returns, const nn::RunningMoments& norm) {
  const torch::Tensor r = CopyFloats(returns, {static_cast<int64_t>(returns.size())});
  return ((r.to(torch::kFloat64) - norm.scalar_mean()) / ReturnStd(norm)).to(torch::kFloat32);
}

double ReturnStd(const nn::RunningMoments& norm) { return std::sqrt(std::max(norm.scalar_var(), kMinReturnVar)); }

}  // namespace imca::learner::internal
