#ifndef IMCA_COMMON_ENV_SCENARIOS_DOOR_SCENARIO_H_
#define IMCA_COMMON_ENV_SCENARIOS_DOOR_SCENARIO_H_

#include <cstdint>
#include <utility>
#include <vector>

#include "common/env/env.h"

namespace imca::env {

// Doors opened by switches, with EDTI's door-open interval `doi` as
// pass_environment.py applies it after each step's moves: an open door whose
// count has reached doi closes, else its count goes up by one; then a closed
// door opens (count 0) if an agent stands on one of its switches. So a door
// is passable for exactly doi + 1 moves after it opens, and doi = 0 means
// open during a move iff a switch was held after the previous one. Episodes
// start with every door closed. z holds one field of BitsFor(doi) bits per
// door: 0 closed, count + 1 while open.
class DoorScenario : public Scenario {
 public:
  DoorScenario(GridMap map, const ScenarioConfig& config, int n, int num_actions, int limit, float success,
               float penalty, int default_timer, bool needs_treasure, bool share_cells)
      : Scenario(std::move(map), config, n, 0, num_actions, limit, success, penalty, share_cells),
        timer_(config.door_timer >= 0 ? config.door_timer : default_timer),
        bits_(BitsFor(timer_)),
        needs_treasure_(needs_treasure),
        goal_room_(map_.GoalRoom()) {}

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

  const int timer_;
  const int bits_;
  const bool needs_treasure_;
  const std::vector<bool> goal_room_;
};

}  // namespace imca::env

#endif  // IMCA_COMMON_ENV_SCENARIOS_DOOR_SCENARIO_H_
