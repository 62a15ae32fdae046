#ifndef IMCA_COMMON_ENV_JOINT_STATE_H_
#define IMCA_COMMON_ENV_JOINT_STATE_H_

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "common/env/env.h"

namespace imca::env {

// A scenario's state as CMAE's gridworld code sees it (docs/baselines.md,
// "CMAE"): a tuple of discrete variables, each agent's
// column x and row y in agent order, then each non-player entity's x and y
// (push_box_cmae: the box centre), then, if the scenario has object bits,
// z (the doors' bits: CMAE's door code up to relabelling) — CMAE's own
// (x1, y1, x2, y2, door) and (x1, y1, x2, y2, box x, box y). The step count
// is not a variable. Coordinates count from the first column and row that
// are not all wall, and range over the floor's extent, so that a map drawn
// with a border has CMAE's ranges (pass_cmae: 30, not 32). The joint state
// index is the variables' mixed-radix number, variable 0 least significant.
// Immutable; thread-safe.
class JointStateSpace {
 public:
  // The largest number of joint states (and of joint states times joint
  // actions, the counters' keys) this space indexes.
  static constexpr double kMaxIndex = 4611686018427387904.0;  // 2^62

  // Errors: INVALID_ARGUMENT when the joint states times the joint actions
  // (num_actions ^ num_agents) exceed 2^62, naming both numbers.
  static absl::StatusOr<JointStateSpace> Create(const Scenario& scenario);

  int num_vars() const { return static_cast<int>(ranges_.size()); }
  // Values each variable takes: the floor's extent across for an x, down
  // for a y, 2^object bits for z.
  const std::vector<int64_t>& ranges() const { return ranges_; }
  // "x1", "y1", .., "x<entity>" as "ex1", "ey1", .., "z".
  const std::string& name(int var) const { return names_[var]; }
  // Joint states: the product of the ranges.
  int64_t size() const { return size_; }
  // Joint actions: num_actions ^ num_agents.
  int64_t joint_actions() const { return joint_actions_; }
  int num_agents() const { return num_agents_; }
  int num_actions() const { return num_actions_; }

  // The variables of a compact state (env.h layout) into vars[0..num_vars).
  void Variables(const int32_t* state, int32_t* vars) const;
  // The joint state index of a compact state, in [0, size()).
  int64_t Index(const int32_t* state) const;
  // The variables of index `index` into vars[0..num_vars).
  void Decode(int64_t index, int32_t* vars) const;
  // Joint action index of actions[0..n): agent 0's the most significant
  // digit (CMAE's a = A * a1 + a2), and back.
  int64_t JointAction(const int32_t* actions) const;
  int32_t AgentAction(int64_t joint_action, int agent) const;

 private:
  JointStateSpace() = default;

  int num_agents_ = 0;
  int num_npcs_ = 0;
  int num_actions_ = 0;
  int width_ = 0;
  int col0_ = 0, row0_ = 0;  // The floor's first column and row.
  bool has_z_ = false;
  std::vector<int64_t> ranges_;
  std::vector<std::string> names_;
  int64_t size_ = 1;
  int64_t joint_actions_ = 1;
};

}  // namespace imca::env

#endif  // IMCA_COMMON_ENV_JOINT_STATE_H_
