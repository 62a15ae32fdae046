#include "common/nn/running_moments.h"

#include <cmath>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"

namespace imca::nn {

RunningMoments::RunningMoments(int64_t dim)
    : mean_(torch::zeros({dim}, torch::kFloat64)), var_(torch::ones({dim}, torch::kFloat64)) {}

void RunningMoments::Update(const torch::Tensor& x) {
  torch::NoGradGuard no_grad;
  const torch::Tensor xd = x.to(torch::kFloat64).reshape({-1, dim()});
  const double rows = static_cast<double>(xd.size(0));
  if (rows == 0) return;
  const torch::Tensor batch_mean = xd.mean(0);
  const torch::Tensor batch_var = (xd - batch_mean).pow(2).mean(0);
  const torch::Tensor delta = batch_mean - mean_;
  const double total = count_ + rows;
  mean_ = mean_ + delta * (rows / total);
  var_ = (var_ * count_ + batch_var * rows + delta * delta * (count_ * rows / total)) / total;
  count_ = total;
}

void RunningMoments::Update(const std::vector<float>& x) {
  if (x.empty()) return;
  Update(torch::from_blob(const_cast<float*>(x.data()), {static_cast<int64_t>(x.size()), 1}, torch::kFloat32));
}

double RunningMoments::scalar_mean() const { return mean_[0].item<double>(); }
double RunningMoments::scalar_var() const { return var_[0].item<double>(); }

torch::Tensor RunningMoments::ToTensor() const {
  return torch::cat({mean_, var_, torch::tensor({count_}, torch::kFloat64)});
}

absl::StatusOr<RunningMoments> RunningMoments::FromTensor(const torch::Tensor& t, int64_t dim,
                                                          const std::string& name) {
  if (t.dim() != 1 || t.size(0) != 2 * dim + 1) {
    return absl::InvalidArgumentError(absl::StrCat("checkpoint ", name, " is not a [", 2 * dim + 1, "] tensor"));
  }
  const torch::Tensor d = t.to(torch::kFloat64).contiguous();
  RunningMoments r(dim);
  r.mean_ = d.slice(0, 0, dim).clone();
  r.var_ = d.slice(0, dim, 2 * dim).clone();
  r.count_ = d[2 * dim].item<double>();
  if (!torch::isfinite(r.mean_).all().item<bool>() || !torch::isfinite(r.var_).all().item<bool>() ||
      !(r.var_ >= 0).all().item<bool>() || !std::isfinite(r.count_) || !(r.count_ > 0)) {
    return absl::InvalidArgumentError(absl::StrCat("checkpoint ", name, " holds invalid statistics"));
  }
  return r;
}

}  // namespace imca::nn
