#ifndef IMCA_COMMON_PROTOCOL_POLICY_NAMES_H_
#define IMCA_COMMON_PROTOCOL_POLICY_NAMES_H_

#include <string>

#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"

namespace imca {

// The tensor names of a published policy (learner_service.proto's Policy),
// spelled once for the writer (common/nn/policy_export.h) and the reader
// (common/protocol/policy_mlp.h). Pure.

// The prefix of network `k` of a policy with `agent_networks` networks:
// "policy." for the one shared network (agent_networks 0), else
// "agent<k>.policy.".
inline std::string PolicyTensorPrefix(int agent_networks, int k) {
  return agent_networks == 0 ? std::string("policy.") : absl::StrCat("agent", k, ".policy.");
}

// "<prefix><layer>.<part>": part "weight" or "bias" of linear layer `layer`,
// or "norm.weight", "norm.bias" of the LayerNorm after it.
inline std::string LayerTensorName(absl::string_view prefix, int layer, absl::string_view part) {
  return absl::StrCat(prefix, layer, ".", part);
}

// "<prefix>input_norm.<part>": the LayerNorm on the input ("weight", "bias").
inline std::string InputNormTensorName(absl::string_view prefix, absl::string_view part) {
  return absl::StrCat(prefix, "input_norm.", part);
}

}  // namespace imca

#endif  // IMCA_COMMON_PROTOCOL_POLICY_NAMES_H_
