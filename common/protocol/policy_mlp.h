#ifndef IMCA_COMMON_PROTOCOL_POLICY_MLP_H_
#define IMCA_COMMON_PROTOCOL_POLICY_MLP_H_

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "absl/status/statusor.h"
#include "imca/v1/learner_service.pb.h"

namespace imca {

// Evaluates a published MLP_TANH, MLP_TANH_LAYERNORM or MLP_RELU
// Policy, shared or one network per agent (see learner_service.proto), with
// Eigen, so actors need no LibTorch. Not thread-safe (scratch buffers are
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
  // 0: shared; else the number of per-agent networks.
  int agent_networks() const { return agent_networks_; }
  // OK if this policy can act in a scenario of these sizes; else
  // INVALID_ARGUMENT saying which size differs.
  absl::Status Fits(int obs_dim, int num_actions, int num_agents) const;

  // obs: [batch][obs_dim] row-major; writes softmax probabilities
  // [batch][num_actions] into probs. With per-agent networks, row r is agent
  // (r mod agent_networks)'s observation ([env][agent] rows).
  void Probabilities(const float* obs, int batch, float* probs);

 private:
  // y = LN(x) applied row-wise: (x - mean) / sqrt(var + eps) * gain + shift.
  struct LayerNorm {
    Eigen::RowVectorXf gain;
    Eigen::RowVectorXf shift;
  };
  static void ApplyLayerNorm(const LayerNorm& norm, Eigen::Ref<Matrix> x);
  // One network: tensors "<prefix><i>.weight" etc.
  struct Net {
    std::vector<Matrix> weights;  // [out, in]
    std::vector<Eigen::RowVectorXf> biases;
    // MLP_TANH_LAYERNORM only: on the input (if the policy has it), and after each hidden tanh.
    std::optional<LayerNorm> input_norm;
    std::vector<LayerNorm> hidden_norms;  // Empty or one per hidden layer.
    Matrix normed_input;
    std::vector<Matrix> scratch;
  };
  static absl::StatusOr<Net> ReadNet(const v1::Policy& policy, const std::string& prefix, bool layer_norm);
  // Logits of `rows` observations into net.scratch.back().
  void Forward(Net& net, Eigen::Ref<const Matrix> x, int rows) const;

  int64_t version_ = 0;
  int obs_dim_ = 0;
  int num_actions_ = 0;
  int agent_networks_ = 0;
  bool relu_ = false;
  std::vector<Net> nets_;  // One, or one per agent.
  Matrix gathered_;  // One agent's rows (agent_networks > 0).
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

// The seed of the stream an actor run with seed `seed` draws its action
// samples from (Actor; ./imca env rollout --seed draws the same).
inline uint64_t ActionSamplingSeed(uint64_t seed) { return seed * 7919 + 17; }

}  // namespace imca

#endif  // IMCA_COMMON_PROTOCOL_POLICY_MLP_H_
