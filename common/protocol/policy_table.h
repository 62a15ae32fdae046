#ifndef IMCA_COMMON_PROTOCOL_POLICY_TABLE_H_
#define IMCA_COMMON_PROTOCOL_POLICY_TABLE_H_

#include <cstdint>
#include <utility>
#include <vector>

#include "absl/container/flat_hash_map.h"
#include "absl/status/statusor.h"
#include "common/env/env.h"
#include "common/env/joint_state.h"
#include "imca/v1/learner_service.pb.h"

namespace imca {

// CMAE's episode length H (its tasks' step limit): by default a CMAE learner
// trains a version on one actor's unroll of this many steps of one
// environment, an episode, as CMAE's own loop updates its tables after
// each (DefaultLearnerConfig, DefaultActorConfig).
inline constexpr int kCmaeEpisodeSteps = 300;

// Evaluates a published TABULAR_Q Policy (CMAE's; learner_service.proto
// TabularPolicy) on compact states of the scenario it was trained on.
// Immutable after FromProto; thread-safe.
class PolicyTable {
 public:
  // Errors: INVALID_ARGUMENT when the policy is not TABULAR_Q, its sizes do
  // not match `scenario` (agents, actions, joint states), or a table is
  // malformed (values not rows x n x A, states not ascending and in range,
  // a value not finite, the weight outside [0, 1]).
  static absl::StatusOr<PolicyTable> FromProto(const v1::Policy& policy, const env::Scenario& scenario);

  int64_t version() const { return version_; }
  double exploit_weight() const { return weight_; }

  // Writes probabilities [num_envs][n][A] of the states [num_envs][K]
  // (env.h layout): uniform over the actions of the greatest value, of
  // (1 - w) explore + w exploit, or with `evaluation` of exploit alone.
  void Probabilities(const int32_t* states, int num_envs, bool evaluation, float* probs) const;

 private:
  PolicyTable(env::JointStateSpace space, int state_size) : space_(std::move(space)), state_size_(state_size) {}
  // Joint state -> its row (n x A values) in the table's values.
  using Rows = absl::flat_hash_map<int64_t, int64_t>;
  static absl::StatusOr<Rows> ReadTable(const v1::QTable& table, const char* name, int64_t row_size,
                                        int64_t joint_states);

  env::JointStateSpace space_;
  int state_size_;
  int64_t version_ = 0;
  double weight_ = 0;
  Rows explore_rows_, exploit_rows_;
  std::vector<double> explore_, exploit_;
};

}  // namespace imca

#endif  // IMCA_COMMON_PROTOCOL_POLICY_TABLE_H_
