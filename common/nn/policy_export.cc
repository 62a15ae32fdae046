#include "common/nn/policy_export.h"

#include <string>

#include "common/protocol/policy_names.h"

namespace imca::nn {
namespace {

void AddTensor(const std::string& name, const torch::Tensor& tensor, v1::Policy* policy) {
  const torch::Tensor t = tensor.detach().to(torch::kFloat32).contiguous();
  v1::NamedTensor* out = policy->add_tensors();
  out->set_name(name);
  for (int64_t d : t.sizes()) out->add_shape(d);
  const float* data = t.data_ptr<float>();
  out->mutable_data()->Add(data, data + t.numel());
}

}  // namespace

v1::Policy ExportPolicy(v1::Policy::Architecture architecture, int64_t version, int obs_dim, int num_actions,
                        const std::vector<const MlpImpl*>& actors, bool per_agent) {
  v1::Policy policy;
  policy.set_version(version);
  policy.set_architecture(architecture);
  policy.set_obs_dim(obs_dim);
  policy.set_num_actions(num_actions);
  const int agent_networks = per_agent ? static_cast<int>(actors.size()) : 0;
  policy.set_agent_networks(agent_networks);
  const bool layer_norm = architecture == v1::Policy::MLP_TANH_LAYERNORM;
  for (size_t k = 0; k < actors.size(); ++k) {
    const MlpImpl& actor = *actors[k];
    const std::string prefix = PolicyTensorPrefix(agent_networks, static_cast<int>(k));
    if (layer_norm && !actor.input_norm().is_empty()) {
      AddTensor(InputNormTensorName(prefix, "weight"), actor.input_norm()->weight, &policy);
      AddTensor(InputNormTensorName(prefix, "bias"), actor.input_norm()->bias, &policy);
    }
    const auto& layers = actor.layers();
    for (size_t i = 0; i < layers.size(); ++i) {
      const int layer = static_cast<int>(i);
      AddTensor(LayerTensorName(prefix, layer, "weight"), layers[i]->weight, &policy);
      AddTensor(LayerTensorName(prefix, layer, "bias"), layers[i]->bias, &policy);
      if (layer_norm && i < actor.norms().size()) {
        AddTensor(LayerTensorName(prefix, layer, "norm.weight"), actor.norms()[i]->weight, &policy);
        AddTensor(LayerTensorName(prefix, layer, "norm.bias"), actor.norms()[i]->bias, &policy);
      }
    }
  }
  return policy;
}

}  // namespace imca::nn
