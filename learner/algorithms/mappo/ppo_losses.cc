#include "learner/algorithms/mappo/ppo_losses.h"

#include <algorithm>
#include <cmath>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"

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

void ReturnNormaliser::Update(const torch::Tensor& returns) {
  const torch::Tensor r = returns.to(torch::kFloat64).reshape({-1});
  if (kind_ == ValueNorm::kBatch) {
    moments_.Update(r);
    return;
  }
  if (r.numel() == 0) return;
  const double batch_mean = r.mean().item<double>();
  const double batch_mean_sq = r.pow(2).mean().item<double>();
  ema_mean_ = ema_mean_ * kEmaBeta + batch_mean * (1 - kEmaBeta);
  ema_mean_sq_ = ema_mean_sq_ * kEmaBeta + batch_mean_sq * (1 - kEmaBeta);
  ema_debias_ = ema_debias_ * kEmaBeta + (1 - kEmaBeta);
}

double ReturnNormaliser::mean() const {
  return kind_ == ValueNorm::kBatch ? moments_.scalar_mean() : ema_mean_ / std::max(ema_debias_, kEmaMinDebias);
}

double ReturnNormaliser::std() const {
  if (kind_ == ValueNorm::kBatch) return std::sqrt(std::max(moments_.scalar_var(), kMinReturnVar));
  const double m = mean();
  return std::sqrt(std::max(ema_mean_sq_ / std::max(ema_debias_, kEmaMinDebias) - m * m, kEmaMinVar));
}

torch::Tensor ReturnNormaliser::Normalise(const torch::Tensor& returns) const {
  return ((returns.to(torch::kFloat64) - mean()) / std()).to(torch::kFloat32);
}

torch::Tensor ReturnNormaliser::ToTensor() const {
  if (kind_ == ValueNorm::kBatch) return moments_.ToTensor();
  return torch::tensor({ema_mean_, ema_mean_sq_, ema_debias_}, torch::kFloat64);
}

absl::StatusOr<ReturnNormaliser> ReturnNormaliser::FromTensor(ValueNorm kind, const torch::Tensor& t,
                                                              const std::string& name) {
  ReturnNormaliser out(kind);
  if (kind == ValueNorm::kBatch) {
    absl::StatusOr<nn::RunningMoments> moments = nn::RunningMoments::FromTensor(t, 1, name);
    if (!moments.ok()) return moments.status();
    out.moments_ = *std::move(moments);
    return out;
  }
  if (t.dim() != 1 || t.size(0) != 3) {
    return absl::InvalidArgumentError(absl::StrCat("checkpoint ", name, " is not a [3] tensor (mean, mean square, debiasing term)"));
  }
  const torch::Tensor v = t.to(torch::kFloat64).contiguous();
  const double mean = v[0].item<double>(), mean_sq = v[1].item<double>(), debias = v[2].item<double>();
  if (!std::isfinite(mean) || !std::isfinite(mean_sq) || !(mean_sq >= 0) || !(debias >= 0 && debias <= 1)) {
    return absl::InvalidArgumentError(absl::StrCat("checkpoint ", name, " holds (", mean, ", ", mean_sq, ", ", debias,
                                                   "), not a moving average's state"));
  }
  out.ema_mean_ = mean;
  out.ema_mean_sq_ = mean_sq;
  out.ema_debias_ = debias;
  return out;
}

}  // namespace imca::learner::internal
