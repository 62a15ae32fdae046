#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "common/env/scenarios/registry.h"

namespace imca::env {
namespace {

// Doors opened by switches, with EDTI's door-open interval `doi` as
// pass_environment.py applies it after each step's moves: an open door whose
// count has reached doi closes, else its count goes up by one; then a closed
// door opens (count 0) if an agent stands on one of its switches. So a door
// is passable for exactly doi + 1 moves after it opens, and doi = 0 means
// open during a move iff a switch was held after the previous one. Episodes
// start with every door closed. z holds one field of BitsFor(doi) bits per
// door: 0 closed, count + 1 while open.
struct DoorRules {
  int num_actions;
  int step_limit;
  float success_reward;
  float step_penalty;
  int door_timer;  // doi when --door_timer is not given.
  // Success also needs an agent on a treasure 'T' (multi_room).
  bool needs_treasure;
  bool agents_share_cells;
};

class DoorRooms final : public Scenario {
 public:
  DoorRooms(std::string name, const DoorRules& rules, GridMap map, const ScenarioConfig& config, int n)
      : Scenario(std::move(map), config, n, 0, rules.num_actions, rules.step_limit, rules.success_reward,
                 rules.step_penalty, rules.agents_share_cells),
        name_(std::move(name)),
        timer_(config.door_timer >= 0 ? config.door_timer : rules.door_timer),
        bits_(BitsFor(timer_)),
        needs_treasure_(rules.needs_treasure),
        goal_room_(map_.GoalRoom()) {}

  absl::string_view name() const override { return name_; }
  int door_timer() const override { return timer_; }
  int num_object_bits() const override { return map_.num_doors() * bits_; }
  bool DoorOpen(const int32_t* state, int door) const override { return Field(state, door) > 0; }

  StepOutcome Step(int32_t* state, const int32_t* actions, Rng& rng, float* rewards) const override {
    const int t = StepAgents(state, actions, rng);
    UpdateDoors(state);
    bool all_in = true, on_treasure = false;
    for (int a = 0; a < num_agents_; ++a) {
      const int cell = state[AgentIndex(a)];
      all_in &= goal_room_[cell];
      for (int32_t treasure : map_.treasures()) on_treasure |= cell == treasure;
    }
    return Finish(t, all_in && (on_treasure || !needs_treasure_), rewards);
  }

 private:
  static bool AnyAgentOn(const int32_t* cells, int n, const std::vector<int32_t>& targets) {
    for (int a = 0; a < n; ++a) {
      for (int32_t cell : targets) {
        if (cells[a] == cell) return true;
      }
    }
    return false;
  }
  // Bits holding 0..doi+1.
  static int BitsFor(int timer) {
    int bits = 1;
    while ((1 << bits) < timer + 2) ++bits;
    return bits;
  }
  uint32_t Field(const int32_t* state, int door) const {
    return (static_cast<uint32_t>(state[kObjectsIndex]) >> (bits_ * door)) & ((1u << bits_) - 1);
  }

  void UpdateDoors(int32_t* state) const {
    uint32_t z = static_cast<uint32_t>(state[kObjectsIndex]);
    const uint32_t mask = (1u << bits_) - 1;
    for (int d = 0; d < map_.num_doors(); ++d) {
      uint32_t field = (z >> (bits_ * d)) & mask;  // 0 closed, count + 1 open.
      if (field > 0) field = field - 1 >= static_cast<uint32_t>(timer_) ? 0 : field + 1;
      if (field == 0 && AnyAgentOn(state + 1, num_agents_, map_.switches(d))) field = 1;
      z = (z & ~(mask << (bits_ * d))) | (field << (bits_ * d));
    }
    state[kObjectsIndex] = static_cast<int32_t>(z);
  }

  const std::string name_;
  const int timer_;
  const int bits_;
  const bool needs_treasure_;
  const std::vector<bool> goal_room_;
};

// A door scenario: its rules here, its layout the map's; `needs`, what its
// map must hold besides doors ("" or the problem).
absl::Status AddDoorRooms(ScenarioRegistry* registry, std::string name, const DoorRules& rules,
                          std::string (*needs)(const GridMap& map)) {
  return registry->Add(MakeRulesEntry<DoorRooms>(std::move(name), rules, 2, [needs](const GridMap& m) {
    const std::string problem = needs(m);
    return problem.empty() ? NeedDoors(m) : problem;
  }));
}

}  // namespace

// multi_room: all agents in the goal room and one on its treasure; 5
// actions, agents never share a cell, doi 0.
absl::Status RegisterMultiRoom(ScenarioRegistry* registry) {
  return AddDoorRooms(registry, "multi_room", {5, 300, 50.0f, 0.1f, 0, true, false},
                      [](const GridMap& m) { return NeedTreasure(m, "a treasure 'T' in the last room"); });
}

// EDTI's Pass and ThreePass (docs/scenarios.md, "pass and secret_room"): 4
// actions, agents move independently and may share a cell, doi 8 (the
// default of EDTI's code).
absl::Status RegisterPass(ScenarioRegistry* registry) {
  return AddDoorRooms(registry, "pass", {4, 300, 1000.0f, 0.0f, 8, false, true},
                      [](const GridMap& m) { return NeedGoalMarker(m, "a goal marker 'G' in the far room"); });
}

absl::Status RegisterSecretRoom(ScenarioRegistry* registry) {
  return AddDoorRooms(registry, "secret_room", {4, 300, 1000.0f, 0.0f, 8, false, true},
                      [](const GridMap& m) { return NeedGoalMarker(m, "a goal marker 'G' in the secret room"); });
}

}  // namespace imca::env
