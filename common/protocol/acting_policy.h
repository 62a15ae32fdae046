#ifndef IMCA_COMMON_PROTOCOL_ACTING_POLICY_H_
#define IMCA_COMMON_PROTOCOL_ACTING_POLICY_H_

#include <cstdint>
#include <optional>
#include <vector>

#include "absl/status/statusor.h"
#include "common/env/env.h"
#include "common/env/featurizer.h"
#include "common/protocol/policy_mlp.h"
#include "common/protocol/policy_table.h"
#include "imca/v1/learner_service.pb.h"

namespace imca {

// A published Policy as actors (and imca_env rollout) act with it, whatever
// its architecture: a network (PolicyMlp) on each agent's observation
// (common/env/featurizer.h), or CMAE's Q-tables (PolicyTable) on the compact state.
// Not thread-safe (a network's scratch buffers); copy it per thread.
class ActingPolicy {
 public:
  // Errors: INVALID_ARGUMENT when the policy cannot be read or does not fit
  // `scenario` (its sizes), saying why.
  static absl::StatusOr<ActingPolicy> FromProto(const v1::Policy& policy, const env::Scenario& scenario);

  int64_t version() const { return table_ ? table_->version() : mlp_->version(); }

  // Probabilities [num_envs][n][A] of states [num_envs][K] (env.h layout).
  // `evaluation`: for evaluation environments (Q-tables act on the
  // exploitation side alone; a network is the same either way).
  void Probabilities(const int32_t* states, int num_envs, bool evaluation, float* probs);

 private:
  explicit ActingPolicy(const env::Scenario& scenario)
      : featurizer_(scenario), n_(scenario.num_agents()), state_size_(scenario.state_size()) {}

  env::Featurizer featurizer_;
  int n_;
  int state_size_;
  std::optional<PolicyMlp> mlp_;
  std::optional<PolicyTable> table_;
  std::vector<float> obs_;  // A network's inputs, [num_envs * n][obs_dim] (the largest batch yet).
};

}  // namespace imca

#endif  // IMCA_COMMON_PROTOCOL_ACTING_POLICY_H_
