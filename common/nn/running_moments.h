#ifndef IMCA_COMMON_NN_RUNNING_MOMENTS_H_
#define IMCA_COMMON_NN_RUNNING_MOMENTS_H_

// LibTorch-only, see common/nn/mlp.h.
#include <torch/torch.h>

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/statusor.h"

namespace imca::nn {

// Running mean and (population) variance per column, in float64, merging
// whole batches with the parallel algorithm of Chan et al. (OpenAI
// baselines' RunningMeanStd). It starts as a tiny pseudo-sample (count 1e-4)
// with mean 0 and variance 1, so the first batch dominates and nothing
// divides by 0. Not thread-safe.
class RunningMoments {
 public:
  explicit RunningMoments(int64_t dim = 1);

  // Merges the rows of `x` ([rows][dim], or [rows] for dim 1).
  void Update(const torch::Tensor& x);
  // Merges the values of a scalar stream (dim 1).
  void Update(const std::vector<float>& x);

  const torch::Tensor& mean() const { return mean_; }  // [dim] float64
  const torch::Tensor& var() const { return var_; }    // [dim] float64
  double count() const { return count_; }
  int64_t dim() const { return mean_.size(0); }
  // Column 0's, for scalar streams.
  double scalar_mean() const;
  double scalar_var() const;

  // [mean (dim), var (dim), count] as float64, for checkpoints (for dim 1
  // the PPO learner's [mean, var, count]).
  torch::Tensor ToTensor() const;
  // Errors: INVALID_ARGUMENT naming `name` if the tensor is not [2 dim + 1]
  // or holds a non-finite mean, a negative variance or a count <= 0.
  static absl::StatusOr<RunningMoments> FromTensor(const torch::Tensor& t, int64_t dim, const std::string& name);

 private:
  torch::Tensor mean_, var_;
  double count_ = 1e-4;
};

}  // namespace imca::nn

#endif  // IMCA_COMMON_NN_RUNNING_MOMENTS_H_
