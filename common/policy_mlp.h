#ifndef IMCA_COMMON_POLICY_MLP_H_
#define IMCA_COMMON_POLICY_MLP_H_

#include <cstdint>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "absl/status/statusor.h"
#include "imca/v1/learner_service.pb.h"

namespace imca {

// Evaluates a published "mlp_tanh" or "mlp_tanh_layernorm" Policy (see
// learner_service.proto) with Eigen, so actors need no LibTorch. Not thread-safe (scratch buffers are
// reused between calls to avoid allocation); copy it per thread.
class PolicyMlp {
 public:
  using Matrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

  // Errors: INVALID_ARGUMENT when the architecture is unknown, a tensor is
  // missing or shapes do not chain from obs_dim to num_actions.
  static absl::StatusOr<PolicyMlp> FromProto(const v1::Policy& policy);

  int64_t version() const { return version_; }
  int obs_dim() const { return obs_dim_; }
  int num_actions() const { return num_actions_; }

  // obs: [batch][obs_dim] row-major; writes softmax probabilities
  // [batch][num_actions] into probs.
  void Probabilities(const float* obs, int batch, float* probs);

 private:
  // y = LN(x) applied row-wise: (x - mean) / sqrt(var + eps) * gain + shift.
  struct LayerNorm {
    Eigen::RowVectorXf gain;
    Eigen::RowVectorXf shift;
  };
  static void ApplyLayerNorm(const LayerNorm& norm, Eigen::Ref<Matrix> x);

  int64_t version_ = 0;
  int obs_dim_ = 0;
  int num_actions_ = 0;
  std::vector<Matrix> weights_;  // [out, in]
  std::vector<Eigen::RowVectorXf> biases_;
  // "mlp_tanh_layernorm" only: on the input, and after each hidden tanh.
  std::optional<LayerNorm> input_norm_;
  std::vector<LayerNorm> hidden_norms_; // Empty or one per hidden layer.
  Matrix normed_input_;
  std::vector<Matrix> scratch_;
};

// Index drawn from the categorical distribution probs[0..count) given a
// uniform u in [0, 1) (the last index absorbs rounding). Pure.
inline int SampleCategorical(const float* probs, int count, double u) {
  double cumulative = 0;
  for (int j = 0; j < count; ++j) {
    cumulative += probs[j];
    if (u < cumulative) return j;
  }
  return count - 1;
}

}  // namespace imca

#endif  // IMCA_COMMON_POLICY_MLP_H_
