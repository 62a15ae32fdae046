#include "common/protocol/policy_mlp.h"

#include <cmath>
#include <map>

#include "absl/strings/str_cat.h"
#include "common/protocol/policy_names.h"

namespace imca {

namespace {

constexpr float kLayerNormEps = 1e-5f;  // LibTorch's default, which the learner uses.

}  // namespace

absl::StatusOr<PolicyMlp::Net> PolicyMlp::ReadNet(const v1::Policy& policy, const std::string& prefix,
                                                  bool layer_norm) {
  std::map<std::string, const v1::NamedTensor*> by_name;
  for (const v1::NamedTensor& t : policy.tensors()) by_name[t.name()] = &t;
  // A LayerNorm of `size` elements whose tensors `name_of("weight")` and
  // `name_of("bias")` name.
  const auto read_norm = [&](const auto& name_of, int64_t size) -> absl::StatusOr<LayerNorm> {
    LayerNorm norm;
    for (const char* part : {"weight", "bias"}) {
      const std::string name = name_of(part);
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
  Net net;
  // The input's LayerNorm is optional: a policy trained without it has none.
  if (layer_norm && (by_name.count(InputNormTensorName(prefix, "weight")) > 0 ||
                     by_name.count(InputNormTensorName(prefix, "bias")) > 0)) {
    absl::StatusOr<LayerNorm> norm =
        read_norm([&](const char* part) { return InputNormTensorName(prefix, part); }, policy.obs_dim());
    if (!norm.ok()) return norm.status();
    net.input_norm = *std::move(norm);
  }
  int64_t in = policy.obs_dim();
  for (int layer = 0;; ++layer) {
    const std::string w_name = LayerTensorName(prefix, layer, "weight");
    const std::string b_name = LayerTensorName(prefix, layer, "bias");
    auto w = by_name.find(w_name);
    if (w == by_name.end()) {
      if (layer == 0) return absl::InvalidArgumentError(absl::StrCat("policy has no tensor ", w_name));
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
    net.weights.push_back(Eigen::Map<const Matrix>(wt.data().data(), wt.shape(0), wt.shape(1)));
    net.biases.push_back(Eigen::Map<const Eigen::RowVectorXf>(bt.data().data(), bt.shape(0)));
    in = wt.shape(0);
    // Every layer but the last is followed by the activation and, here, a
    // LayerNorm; which layer is last shows only once the next weight is missing.
    if (layer_norm && by_name.count(LayerTensorName(prefix, layer + 1, "weight")) > 0) {
      absl::StatusOr<LayerNorm> norm = read_norm(
          [&](const char* part) { return LayerTensorName(prefix, layer, absl::StrCat("norm.", part)); }, in);
      if (!norm.ok()) return norm.status();
      net.hidden_norms.push_back(*std::move(norm));
    }
  }
  if (in != policy.num_actions()) {
    return absl::InvalidArgumentError(
        absl::StrCat(prefix, " output size ", in, " != num_actions ", policy.num_actions()));
  }
  net.scratch.resize(net.weights.size());
  return net;
}

absl::StatusOr<PolicyMlp> PolicyMlp::FromProto(const v1::Policy& policy) {
  const v1::Policy::Architecture arch = policy.architecture();
  if (arch != v1::Policy::MLP_TANH && arch != v1::Policy::MLP_TANH_LAYERNORM && arch != v1::Policy::MLP_RELU) {
    return absl::InvalidArgumentError(absl::StrCat("policy.architecture ", static_cast<int>(arch), " (",
                                                   v1::Policy::Architecture_Name(arch),
                                                   ") is not MLP_TANH, MLP_TANH_LAYERNORM or MLP_RELU"));
  }
  const bool layer_norm = arch == v1::Policy::MLP_TANH_LAYERNORM;
  if (policy.obs_dim() < 1) return absl::InvalidArgumentError("policy.obs_dim must be >= 1");
  if (policy.agent_networks() < 0 || policy.agent_networks() > 1024) {
    return absl::InvalidArgumentError(
        absl::StrCat("policy.agent_networks is ", policy.agent_networks(), ", expected 0 (shared) or 1..1024"));
  }
  PolicyMlp mlp;
  mlp.version_ = policy.version();
  mlp.obs_dim_ = policy.obs_dim();
  mlp.num_actions_ = policy.num_actions();
  mlp.agent_networks_ = policy.agent_networks();
  mlp.relu_ = arch == v1::Policy::MLP_RELU;
  for (int k = 0; k < std::max(1, mlp.agent_networks_); ++k) {
    absl::StatusOr<Net> net =
        ReadNet(policy, PolicyTensorPrefix(mlp.agent_networks_, k), layer_norm);
    if (!net.ok()) return net.status();
    mlp.nets_.push_back(*std::move(net));
  }
  return mlp;
}

absl::Status PolicyMlp::Fits(int obs_dim, int num_actions, int num_agents) const {
  if (obs_dim_ != obs_dim || num_actions_ != num_actions) {
    return absl::InvalidArgumentError(absl::StrCat("the policy's observation or action size (", obs_dim_, ", ",
                                                   num_actions_, ") differs from the scenario's (", obs_dim, ", ",
                                                   num_actions, ")"));
  }
  if (agent_networks_ != 0 && agent_networks_ != num_agents) {
    return absl::InvalidArgumentError(absl::StrCat("the policy has networks for ", agent_networks_,
                                                   " agents, the scenario has ", num_agents));
  }
  return absl::OkStatus();
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

void PolicyMlp::Forward(Net& net, Eigen::Ref<const Matrix> raw, int batch) const {
  const size_t layers = net.weights.size();
  // Scratch only grows, so alternating batch sizes allocate nothing.
  if (net.input_norm.has_value()) {
    if (net.normed_input.rows() < batch) net.normed_input.resize(batch, obs_dim_);
    net.normed_input.topRows(batch) = raw;
    ApplyLayerNorm(*net.input_norm, net.normed_input.topRows(batch));
  }
  for (size_t i = 0; i < layers; ++i) {
    if (net.scratch[i].rows() < batch) net.scratch[i].resize(batch, net.weights[i].rows());
    auto out = net.scratch[i].topRows(batch);
    if (i > 0) {
      out.noalias() = net.scratch[i - 1].topRows(batch) * net.weights[i].transpose();
    } else if (net.input_norm.has_value()) {
      out.noalias() = net.normed_input.topRows(batch) * net.weights[i].transpose();
    } else {
      out.noalias() = raw * net.weights[i].transpose();
    }
    out.rowwise() += net.biases[i];
    if (i + 1 < layers) {
      if (relu_) {
        out = out.array().max(0.0f);
      } else {
        out = out.array().tanh();
      }
      if (!net.hidden_norms.empty()) ApplyLayerNorm(net.hidden_norms[i], out);
    }
  }
}

void PolicyMlp::Probabilities(const float* obs, int batch, float* probs) {
  Eigen::Map<const Matrix> raw(obs, batch, obs_dim_);
  Eigen::Map<Matrix> p(probs, batch, num_actions_);
  const auto softmax_rows = [&](const auto& logits, const auto& row_of) {
    for (int r = 0; r < logits.rows(); ++r) {
      const float max = logits.row(r).maxCoeff();
      auto out = p.row(row_of(r));
      out = (logits.row(r).array() - max).exp();
      out /= out.sum();
    }
  };
  if (agent_networks_ == 0) {
    Forward(nets_[0], raw, batch);
    softmax_rows(nets_[0].scratch.back().topRows(batch), [](int r) { return r; });
    return;
  }
  const int k = agent_networks_;
  const int most = (batch + k - 1) / k;
  if (gathered_.rows() < most) gathered_.resize(most, obs_dim_);
  for (int a = 0; a < k; ++a) {
    const int rows = (batch - a + k - 1) / k;  // Rows r * k + a < batch (every row, for any batch).
    if (rows <= 0) continue;
    for (int r = 0; r < rows; ++r) gathered_.row(r) = raw.row(r * k + a);
    Forward(nets_[a], gathered_.topRows(rows), rows);
    softmax_rows(nets_[a].scratch.back().topRows(rows), [&](int r) { return r * k + a; });
  }
}

}  // namespace imca
