#ifndef IMCA_COMMON_NN_POLICY_EXPORT_H_
#define IMCA_COMMON_NN_POLICY_EXPORT_H_

#include <cstdint>
#include <vector>

#include "common/nn/mlp.h"
#include "imca/v1/learner_service.pb.h"

namespace imca::nn {

// The acting networks as a published policy (learner_service.proto's
// Policy), the one export of every algorithm: `architecture`, `version`,
// the sizes, and each network's tensors (float32, row-major) under the
// protocol's names (common/protocol/policy_names.h). One network is shared by every
// agent unless `per_agent`, where network k is agent k's (agent_networks =
// actors.size()). MLP_TANH_LAYERNORM exports the networks' LayerNorms too
// (they must have them). Not thread-safe against training the networks.
v1::Policy ExportPolicy(v1::Policy::Architecture architecture, int64_t version, int obs_dim, int num_actions,
                        const std::vector<const MlpImpl*>& actors, bool per_agent);

}  // namespace imca::nn

#endif  // IMCA_COMMON_NN_POLICY_EXPORT_H_
