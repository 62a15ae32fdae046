#include <cmath>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "common/env/scenarios/registry.h"

namespace imca::env {
namespace {

// The task versions of the methods published after EDTI (docs/scenarios.md,
// "The task versions of CMAE and MACE"), as CMAE's env/rooms.py and env/secret_rooms.py and MACE's
// room.py and secret_rooms.py run them: 4 actions, agents that may share a
// cell and start on fixed cells, every door closed at the start. Each step
// the agents move through the doors of the previous step; then every door is
// recomputed from the new positions: a switch is active if an agent is
// within a Euclidean distance of it (no timer), and a door is open if one of
// its switches is active ('*' opens every door). With first_switch_only
// (CMAE's secret_room) only the first active switch acts, in the order '*',
// then the switches of door A, B, ... Success: every agent inside the goal
// rectangle. z bit d: door d open.
struct SwitchRoomRules {
  double radius;
  bool first_switch_only;
  // The goal rectangle in map coordinates (the border included), inclusive.
  int min_row, max_row, min_col, max_col;
  float success_reward;
};

class SwitchRooms final : public Scenario {
 public:
  SwitchRooms(std::string name, const SwitchRoomRules& rules, GridMap map, const ScenarioConfig& config, int n)
      : Scenario(std::move(map), config, n, 0, 4, 300, rules.success_reward, 0.0f, /*agents_share_cells=*/true),
        name_(std::move(name)),
        rules_(rules) {
    // Switches in the order CMAE's secret_room tries them: '*', then by door.
    for (int cell = 0; cell < map_.num_cells(); ++cell) {
      if (map_.SwitchAt(cell) == GridMap::kEveryDoor) switch_order_.push_back(cell);
    }
    for (int d = 0; d < map_.num_doors(); ++d) {
      for (int cell = 0; cell < map_.num_cells(); ++cell) {
        if (map_.SwitchAt(cell) == d) switch_order_.push_back(cell);
      }
    }
  }

  absl::string_view name() const override { return name_; }
  int num_object_bits() const override { return map_.num_doors(); }
  bool DoorOpen(const int32_t* state, int door) const override {
    return (static_cast<uint32_t>(state[kObjectsIndex]) >> door) & 1u;
  }

  StepOutcome Step(int32_t* state, const int32_t* actions, Rng& rng, float* rewards) const override {
    const int t = StepAgents(state, actions, rng);
    const uint32_t every = (1u << map_.num_doors()) - 1;
    uint32_t z = 0;
    for (int32_t sw : switch_order_) {
      if (!Active(state, sw)) continue;
      const int opens = map_.SwitchAt(sw);
      z |= opens == GridMap::kEveryDoor ? every : 1u << opens;
      if (rules_.first_switch_only) break;
    }
    state[kObjectsIndex] = static_cast<int32_t>(z);
    bool all_in = true;
    for (int a = 0; a < num_agents_; ++a) {
      const int row = map_.Row(state[AgentIndex(a)]), col = map_.Col(state[AgentIndex(a)]);
      all_in &= row >= rules_.min_row && row <= rules_.max_row && col >= rules_.min_col && col <= rules_.max_col;
    }
    return Finish(t, all_in, rewards);
  }

 private:
  bool Active(const int32_t* state, int32_t sw) const {
    for (int a = 0; a < num_agents_; ++a) {
      const int dr = map_.Row(state[AgentIndex(a)]) - map_.Row(sw);
      const int dc = map_.Col(state[AgentIndex(a)]) - map_.Col(sw);
      // sqrt(d2) <= r as the Python code compares, on integer d2.
      if (std::sqrt(static_cast<double>(dr * dr + dc * dc)) <= rules_.radius) return true;
    }
    return false;
  }

  const std::string name_;
  const SwitchRoomRules rules_;
  std::vector<int32_t> switch_order_;
};

// A task version: its rules are the released code's (docs/scenarios.md,
// "The task versions of CMAE and MACE"), its layout the map's.
absl::Status AddSwitchRooms(ScenarioRegistry* registry, std::string name, SwitchRoomRules rules, int agents,
                            ScenarioTuning tuning = {}) {
  return registry->Add(MakeRulesEntry<SwitchRooms>(std::move(name), rules, agents, NeedDoors, tuning));
}

}  // namespace

// CMAE's tasks pay +1 on success where EDTI's pay +1000: the bonuses at the
// ratio to the task's reward they have on pass and secret_room (count beta
// 5e-4, EDTI's curiosity 0.01), measured in docs/results.md ("the bonus at
// the task's scale"). MACE's tasks (+100) were not measured and keep the
// defaults.
const ScenarioTuning kCmaeRewardTuning{/*batch_steps=*/{}, /*learning_rate=*/{}, /*separate_optimizers=*/{},
                                       /*unroll_length=*/{}, /*bonus_scale=*/1e-3};

absl::Status RegisterPassCmae(ScenarioRegistry* registry) {
  return AddSwitchRooms(registry, "pass_cmae", {4.5, false, 1, 30, 17, 30, 1.0f}, 2, kCmaeRewardTuning);
}
absl::Status RegisterSecretRoomCmae(ScenarioRegistry* registry) {
  return AddSwitchRooms(registry, "secret_room_cmae", {1.5, true, 1, 10, 15, 25, 1.0f}, 2, kCmaeRewardTuning);
}
absl::Status RegisterPassMace(ScenarioRegistry* registry) {
  return AddSwitchRooms(registry, "pass_mace", {1.0, false, 1, 30, 17, 30, 100.0f}, 2);
}
absl::Status RegisterSecretRoomMace(ScenarioRegistry* registry) {
  return AddSwitchRooms(registry, "secret_room_mace", {1.0, false, 1, 10, 17, 30, 100.0f}, 2);
}
absl::Status RegisterMultiRoom3Mace(ScenarioRegistry* registry) {
  return AddSwitchRooms(registry, "multi_room3_mace", {1.0, false, 12, 20, 17, 30, 100.0f}, 3);
}

}  // namespace imca::env
