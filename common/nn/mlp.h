#ifndef IMCA_COMMON_NN_MLP_H_
#define IMCA_COMMON_NN_MLP_H_

// LibTorch-only: the one set of torch building blocks (MLP, running moments,
// archives, exception boundary). Include from .cc files that compile torch
// anyway, never from a header that gRPC, environment or test code includes.
#include <torch/torch.h>

#include <cmath>
#include <cstdint>
#include <vector>

#include "absl/status/status.h"

namespace imca::nn {

enum class Activation { kTanh, kRelu };

// x -> Linear -> act -> ... -> Linear (no activation on the output).
struct MlpOptions {
  explicit MlpOptions(std::vector<int64_t> sizes) : sizes_(std::move(sizes)) {}
  // Layer widths: input, hidden..., output (at least two entries).
  TORCH_ARG(std::vector<int64_t>, sizes);
  TORCH_ARG(Activation, activation) = Activation::kRelu;
  // Orthogonal-init gains of the hidden layers and of the output layer;
  // biases start at 0.
  TORCH_ARG(double, hidden_gain) = std::sqrt(2.0);
  TORCH_ARG(double, last_gain) = std::sqrt(2.0);
  // LayerNorm (eps 1e-5, weight 1, bias 0) after each hidden activation (as
  // on-policy's MLPLayer), and with input_norm on the input too (its
  // MLPBase's feature normalisation).
  TORCH_ARG(bool, layer_norm) = false;
  TORCH_ARG(bool, input_norm) = true;  // With layer_norm only.
  // The initial weights are drawn from a generator of their own seeded with
  // this, so building a network neither reads nor reseeds torch's global
  // generator's stream that other code relies on.
  TORCH_ARG(uint64_t, seed) = 0;
};

// Submodules are named "0", "1", ... (Linear), "input_norm" and "norm<i>"
// (LayerNorm after hidden layer i): checkpoints and published policies use
// these names. Not thread-safe for training; forward passes under
// NoGradGuard may run concurrently.
class MlpImpl : public torch::nn::Module {
 public:
  explicit MlpImpl(const MlpOptions& options);

  torch::Tensor forward(torch::Tensor x);
  // The rest of forward after layer `layer`'s Linear: from its output
  // (pre-activation) on. forward(x) is ForwardFrom(layers()[0](norm(x)), 0);
  // a caller that computes the first layer in parts (MADDPG's critic, whose
  // joint-observation part is the same for every agent) continues here.
  torch::Tensor ForwardFrom(torch::Tensor pre_activation, size_t layer);

  const MlpOptions& options() const { return options_; }
  std::vector<torch::nn::Linear>& layers() { return layers_; }
  const std::vector<torch::nn::Linear>& layers() const { return layers_; }
  // Empty without layer_norm and input_norm.
  const torch::nn::LayerNorm& input_norm() const { return input_norm_; }
  const std::vector<torch::nn::LayerNorm>& norms() const { return norms_; }

 private:
  MlpOptions options_;
  torch::nn::LayerNorm input_norm_{nullptr};
  std::vector<torch::nn::Linear> layers_;
  std::vector<torch::nn::LayerNorm> norms_;
};
TORCH_MODULE(Mlp);

// Fills `weight` ([out][in...]) with a (semi-)orthogonal matrix times `gain`
// drawn from `generator`: torch.nn.init.orthogonal_'s algorithm (QR of a
// standard normal matrix, signs fixed by R's diagonal) with a caller's
// generator.
void OrthogonalInit(torch::Tensor weight, double gain, at::Generator& generator);

// Copies every parameter and buffer of `from` into `to` (same architecture):
// tau 1 is a hard copy, else the soft (Polyak) update to <- tau from + (1 - tau) to.
void SoftUpdate(torch::nn::Module& to, const torch::nn::Module& from, double tau);

// A seed for stream `stream` of `seed` (splitmix), so that the networks of
// one component each get their own initial weights from one user seed.
uint64_t SubSeed(uint64_t seed, uint64_t stream);

// Sets layer `layer` of `mlp` to weight [out][in] and bias [out] (tests
// with hand-worked numbers). Errors: INVALID_ARGUMENT on a bad layer or shape.
absl::Status SetLinear(Mlp& mlp, int layer, const std::vector<float>& weight, const std::vector<float>& bias);

}  // namespace imca::nn

#endif  // IMCA_COMMON_NN_MLP_H_
