#include "common/policy_mlp.h"

#include <map>

#include "absl/strings/str_cat.h"

namespace imca {

absl::StatusOr<PolicyMlp> PolicyMlp::FromProto(const v1::Policy& policy) {
  if (policy.architecture() != "mlp_tanh") {
    return absl::InvalidArgumentError(
        absl::StrCat("policy.architecture '", policy.architecture(), "' is not mlp_tanh"));
  }
  std::map<std::string, const v1::NamedTensor*> by_name;
  for (const v1::NamedTensor& t : policy.tensors()) by_name[t.name()] = &t;
  PolicyMlp mlp;
  mlp.version_ = policy.version();
  mlp.obs_dim_ = policy.obs_dim();
  mlp.num_actions_ = policy.num_actions();
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
  }
  if (in != policy.num_actions()) {
    return absl::InvalidArgumentError(
        absl::StrCat("policy output size ", in, " != num_actions ", policy.num_actions()));
  }
  mlp.scratch_.resize(mlp.weights_.size());
  return mlp;
}

void PolicyMlp::Probabilities(const float* obs, int batch, float* probs) {
  Eigen::Map<const Matrix> x(obs, batch, obs_dim_);
  const size_t layers = weights_.size();
  // Scratch only grows, so alternating batch sizes allocate nothing.
  for (size_t i = 0; i < layers; ++i) {
    if (scratch_[i].rows() < batch) scratch_[i].resize(batch, weights_[i].rows());
    auto out = scratch_[i].topRows(batch);
    if (i == 0) {
      out.noalias() = x * weights_[i].transpose();
    } else {
      out.noalias() = scratch_[i - 1].topRows(batch) * weights_[i].transpose();
    }
    out.rowwise() += biases_[i];
    if (i + 1 < layers) out = out.array().tanh();
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
