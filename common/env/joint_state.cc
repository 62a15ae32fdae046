#include "common/env/joint_state.h"

#include <algorithm>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace imca::env {

absl::StatusOr<JointStateSpace> JointStateSpace::Create(const Scenario& scenario) {
  JointStateSpace space;
  space.num_agents_ = scenario.num_agents();
  space.num_npcs_ = scenario.num_npcs();
  space.num_actions_ = scenario.num_actions();
  const GridMap& map = scenario.map();
  space.width_ = map.width();
  int col_min = map.width(), col_max = -1, row_min = map.height(), row_max = -1;
  for (int cell = 0; cell < map.num_cells(); ++cell) {
    if (map.IsWall(cell)) continue;
    col_min = std::min(col_min, map.Col(cell));
    col_max = std::max(col_max, map.Col(cell));
    row_min = std::min(row_min, map.Row(cell));
    row_max = std::max(row_max, map.Row(cell));
  }
  if (col_max < 0) return absl::InvalidArgumentError(absl::StrCat(scenario.name(), ": the map has no floor"));
  space.col0_ = col_min;
  space.row0_ = row_min;
  const int64_t width = col_max - col_min + 1, height = row_max - row_min + 1;
  for (int a = 0; a < space.num_agents_; ++a) {
    space.ranges_.insert(space.ranges_.end(), {width, height});
    space.names_.insert(space.names_.end(), {absl::StrCat("x", a + 1), absl::StrCat("y", a + 1)});
  }
  for (int j = 0; j < space.num_npcs_; ++j) {
    space.ranges_.insert(space.ranges_.end(), {width, height});
    space.names_.insert(space.names_.end(), {absl::StrCat("ex", j + 1), absl::StrCat("ey", j + 1)});
  }
  if (scenario.num_object_bits() > 0) {
    space.has_z_ = true;
    space.ranges_.push_back(int64_t{1} << scenario.num_object_bits());
    space.names_.push_back("z");
  }
  double states = 1, actions = 1;
  for (int64_t range : space.ranges_) states *= static_cast<double>(range);
  for (int a = 0; a < space.num_agents_; ++a) actions *= space.num_actions_;
  if (states * actions > kMaxIndex) {
    return absl::InvalidArgumentError(absl::StrFormat(
        "the joint state of %s takes %.3g values and its joint action %.3g: more than the 2^62 (state, "
        "joint action) pairs a tabular learner indexes",
        scenario.name(), states, actions));
  }
  for (int64_t range : space.ranges_) space.size_ *= range;
  for (int a = 0; a < space.num_agents_; ++a) space.joint_actions_ *= space.num_actions_;
  return space;
}

void JointStateSpace::Variables(const int32_t* state, int32_t* vars) const {
  int v = 0;
  for (int i = 0; i < num_agents_ + num_npcs_; ++i) {
    const int32_t cell = state[1 + i];
    vars[v++] = cell % width_ - col0_;
    vars[v++] = cell / width_ - row0_;
  }
  if (has_z_) vars[v] = state[kObjectsIndex];
}

int64_t JointStateSpace::Index(const int32_t* state) const {
  int32_t vars[2 * (kMaxAgents + kMaxNpcs) + 1];
  Variables(state, vars);
  int64_t index = 0;
  for (int v = num_vars() - 1; v >= 0; --v) index = index * ranges_[v] + vars[v];
  return index;
}

void JointStateSpace::Decode(int64_t index, int32_t* vars) const {
  for (int v = 0; v < num_vars(); ++v) {
    vars[v] = static_cast<int32_t>(index % ranges_[v]);
    index /= ranges_[v];
  }
}

int64_t JointStateSpace::JointAction(const int32_t* actions) const {
  int64_t joint = 0;
  for (int a = 0; a < num_agents_; ++a) joint = joint * num_actions_ + actions[a];
  return joint;
}

int32_t JointStateSpace::AgentAction(int64_t joint_action, int agent) const {
  for (int a = num_agents_ - 1; a > agent; --a) joint_action /= num_actions_;
  return static_cast<int32_t>(joint_action % num_actions_);
}

}  // namespace imca::env
