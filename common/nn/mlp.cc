#include "common/nn/mlp.h"

#include <ATen/CPUGeneratorImpl.h>

#include <string>

#include "absl/strings/str_cat.h"
#include "common/base/rng.h"

namespace imca::nn {

constexpr double kLayerNormEps = 1e-5;

void OrthogonalInit(torch::Tensor weight, double gain, at::Generator& generator) {
  torch::NoGradGuard no_grad;
  const int64_t rows = weight.size(0);
  const int64_t cols = weight.numel() / rows;
  torch::Tensor flat = torch::randn({rows, cols}, generator, weight.options());
  if (rows < cols) flat = flat.t();
  auto [q, r] = torch::linalg_qr(flat);
  q = q * torch::diag(r, 0).sign();
  if (rows < cols) q = q.t();
  weight.copy_(q.reshape(weight.sizes()) * gain);
}

uint64_t SubSeed(uint64_t seed, uint64_t stream) {
  uint64_t state = seed ^ (stream * 0xd1b54a32d192ed03ULL);
  return Rng::SplitMix64(state);
}

MlpImpl::MlpImpl(const MlpOptions& options) : options_(options) {
  const std::vector<int64_t>& sizes = options.sizes();
  TORCH_CHECK(sizes.size() >= 2, "an MLP needs an input and an output size");
  for (int64_t s : sizes) TORCH_CHECK(s >= 1, "MLP layer sizes must be >= 1");
  at::Generator generator = at::detail::createCPUGenerator(options.seed());
  if (options.layer_norm() && options.input_norm()) {
    input_norm_ = register_module(
        "input_norm", torch::nn::LayerNorm(torch::nn::LayerNormOptions({sizes[0]}).eps(kLayerNormEps)));
  }
  const size_t count = sizes.size() - 1;
  for (size_t i = 0; i < count; ++i) {
    torch::nn::Linear layer(sizes[i], sizes[i + 1]);
    OrthogonalInit(layer->weight, i + 1 == count ? options.last_gain() : options.hidden_gain(), generator);
    torch::nn::init::zeros_(layer->bias);
    layers_.push_back(register_module(std::to_string(i), layer));
    if (options.layer_norm() && i + 1 < count) {
      norms_.push_back(register_module(
          "norm" + std::to_string(i),
          torch::nn::LayerNorm(torch::nn::LayerNormOptions({sizes[i + 1]}).eps(kLayerNormEps))));
    }
  }
}

torch::Tensor MlpImpl::forward(torch::Tensor x) {
  if (!input_norm_.is_empty()) x = input_norm_->forward(x);
  return ForwardFrom(layers_[0]->forward(x), 0);
}

torch::Tensor MlpImpl::ForwardFrom(torch::Tensor x, size_t layer) {
  for (size_t i = layer; i + 1 < layers_.size(); ++i) {
    x = options_.activation() == Activation::kTanh ? torch::tanh(x) : torch::relu(x);
    if (!norms_.empty()) x = norms_[i]->forward(x);
    x = layers_[i + 1]->forward(x);
  }
  return x;
}

void SoftUpdate(torch::nn::Module& to, const torch::nn::Module& from, double tau) {
  torch::NoGradGuard no_grad;
  const std::vector<torch::Tensor> source = from.parameters();
  std::vector<torch::Tensor> target = to.parameters();
  TORCH_CHECK(source.size() == target.size(), "SoftUpdate: different architectures");
  for (size_t i = 0; i < source.size(); ++i) {
    if (tau >= 1) {
      target[i].copy_(source[i]);
    } else {
      target[i].mul_(1 - tau).add_(source[i], tau);
    }
  }
  const std::vector<torch::Tensor> source_buffers = from.buffers();
  std::vector<torch::Tensor> target_buffers = to.buffers();
  for (size_t i = 0; i < source_buffers.size() && i < target_buffers.size(); ++i) {
    target_buffers[i].copy_(source_buffers[i]);
  }
}

absl::Status SetLinear(Mlp& mlp, int layer, const std::vector<float>& weight, const std::vector<float>& bias) {
  if (layer < 0 || layer >= static_cast<int>(mlp->layers().size())) {
    return absl::InvalidArgumentError(absl::StrCat("no layer ", layer));
  }
  torch::nn::Linear& linear = mlp->layers()[layer];
  if (static_cast<int64_t>(weight.size()) != linear->weight.numel() ||
      static_cast<int64_t>(bias.size()) != linear->bias.numel()) {
    return absl::InvalidArgumentError(absl::StrCat("layer ", layer, " is ", linear->weight.size(0), "x",
                                                   linear->weight.size(1)));
  }
  torch::NoGradGuard no_grad;
  linear->weight.copy_(torch::tensor(weight).reshape(linear->weight.sizes()));
  linear->bias.copy_(torch::tensor(bias));
  return absl::OkStatus();
}

}  // namespace imca::nn
