#include "common/policy_mlp.h"

#include <cmath>
#include <map>

#include "absl/strings/str_cat.h"

namespace imca {

namespace {

constexpr float kLayerNormEps = 1e-5f;  // LibTorch's default, which the learner uses.

}  // namespace

absl::StatusOr<PolicyMlp> PolicyMlp::FromProto(const v1::Policy& policy) {
  const bool layer_norm = policy.architecture() == "mlp_tanh_layernorm";
  if (policy.architecture() != "mlp_tanh" && !layer_norm) {
    return absl::InvalidArgumentError(absl::StrCat("policy.architecture '", policy.architecture(),
                                                   "' is not mlp_tanh or mlp_tanh_layernorm"));
  }
  std::map<std::string, const v1::NamedTensor*> by_name;
  for (const v1::NamedTensor& t : policy.tensors()) by_name[t.name()] = &t;
  // A LayerNorm "<prefix>.weight" / "<prefix>.bias" of `size` elements.
  const auto read_norm = [&](const std::string& prefix, int64_t size) -> absl::StatusOr<LayerNorm> {
    LayerNorm norm;
    for (const char* part : {"weight", "bias"}) {
      const std::string name = absl::StrCat(prefix, ".", part);
      auto it = by_name.find(name);
      if (it == by_name.end()) return absl::InvalidArgumentError(absl::StrCat("policy lacks ", name));
      const v1::NamedTensor& t = *it->second;
      if (t.shape_size() != 1 || t.shape(0) != size || t.data_size() != size) {
        return absl::InvalidArgumentError(absl::StrCat(name, " has a bad shape or size (expected ", size, ")"));
      }
      (part[0] == 'w' ? norm.gain : norm.shift) = Eigen::Map<const Eigen::RowVectorXf>(t.data().data(), size);
    }
    return norm;
  };
  PolicyMlp mlp;
  mlp.version_ = policy.version();
  mlp.obs_dim_ = policy.obs_dim();
  mlp.num_actions_ = policy.num_actions();
  if (policy.obs_dim() < 1) return absl::InvalidArgumentError("policy.obs_dim must be >= 1");
  if (layer_norm) {
    absl::StatusOr<LayerNorm> norm = read_norm("policy.input_norm", policy.obs_dim());
    if (!norm.ok()) return norm.status();
    mlp.input_norm_ = *std::move(norm);
  }
  int64_t in = policy.obs_dim();
  for (int layer = 0;; ++layer) {
    const std::string w_name = absl::StrCat("policy.", layer, ".weight");
    const std::string b_name = absl::StrCat("policy.", layer, ".bias");
    auto w = by_name.find(w_name);
    if (w == by_name.end()) {
      if (layer == 0) return absl::InvalidArgumentError("policy has no tensor policy.0.weight");
      break;
    }
    auto b = by_name.find(b_name);
    if (b == by_name.end()) return absl::InvalidArgumentError(absl::StrCat("policy lacks ", b_name));
    const v1::NamedTensor& wt = *w->second;
    const v1::NamedTensor& bt = *b->second;
    if (wt.shape_size() != 2 || wt.shape(1) != in || wt.shape(0) < 1 ||
        wt.data_size() != wt.shape(0) * wt.shape(1)) {
      return absl::InvalidArgumentError(absl::StrCat(w_name, " has a bad shape or size (input ", in, ")"));
    }
    if (bt.shape_size() != 1 || bt.shape(0) != wt.shape(0) || bt.data_size() != bt.shape(0)) {
      return absl::InvalidArgumentError(absl::StrCat(b_name, " has a bad shape or size"));
    }
    mlp.weights_.push_back(Eigen::Map<const Matrix>(wt.data().data(), wt.shape(0), wt.shape(1)));
    mlp.biases_.push_back(Eigen::Map<const Eigen::RowVectorXf>(bt.data().data(), bt.shape(0)));
    in = wt.shape(0);
    // Every layer but the last is followed by tanh and, here, a LayerNorm;
    // which layer is last shows only once the next weight is missing.
    if (layer_norm && by_name.count(absl::StrCat("policy.", layer + 1, ".weight")) > 0) {
      absl::StatusOr<LayerNorm> norm = read_norm(absl::StrCat("policy.", layer, ".norm"), in);
      if (!norm.ok()) return norm.status();
      mlp.hidden_norms_.push_back(*std::move(norm));
    }
  }
  if (in != policy.num_actions()) {
    return absl::InvalidArgumentError(
        absl::StrCat("policy output size ", in, " != num_actions ", policy.num_actions()));
  }
  mlp.scratch_.resize(mlp.weights_.size());
  return mlp;
}

void PolicyMlp::ApplyLayerNorm(const LayerNorm& norm, Eigen::Ref<Matrix> x) {
  const Eigen::Index cols = x.cols();
  for (Eigen::Index r = 0; r < x.rows(); ++r) {
    auto row = x.row(r);
    const float mean = row.sum() / cols;
    const float var = (row.array() - mean).square().sum() / cols;  // Biased, as LibTorch.
    const float inv = 1.0f / std::sqrt(var + kLayerNormEps);
    row = ((row.array() - mean) * inv) * norm.gain.array() + norm.shift.array();
  }
}

void PolicyMlp::Probabilities(const float* obs, int batch, float* probs) {
  Eigen::Map<const Matrix> raw(obs, batch, obs_dim_);
  const size_t layers = weights_.size();
  // Scratch only grows, so alternating batch sizes allocate nothing.
  if (input_norm_.has_value()) {
    if (normed_input_.rows() < batch) normed_input_.resize(batch, obs_dim_);
    normed_input_.topRows(batch) = raw;
    ApplyLayerNorm(*input_norm_, normed_input_.topRows(batch));
  }
  for (size_t i = 0; i < layers; ++i) {
    if (scratch_[i].rows() < batch) scratch_[i].resize(batch, weights_[i].rows());
    auto out = scratch_[i].topRows(batch);
    if (i > 0) {
      out.noalias() = scratch_[i - 1].topRows(batch) * weights_[i].transpose();
    } else if (input_norm_.has_value()) {
      out.noalias() = normed_input_.topRows(batch) * weights_[i].transpose();
    } else {
      out.noalias() = raw * weights_[i].transpose();
    }
    out.rowwise() += biases_[i];
    if (i + 1 < layers) {
      out = out.array().tanh();
      if (!hidden_norms_.empty()) ApplyLayerNorm(hidden_norms_[i], out);
    }
  }
  const auto logits = scratch_[layers - 1].topRows(batch);
  Eigen::Map<Matrix> p(probs, batch, num_actions_);
  for (int r = 0; r < batch; ++r) {
    const float max = logits.row(r).maxCoeff();
    p.row(r) = (logits.row(r).array() - max).exp();
    p.row(r) /= p.row(r).sum();
  }
}

}  // namespace imca
