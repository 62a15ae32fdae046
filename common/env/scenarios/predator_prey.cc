#include <cstdint>
#include <utility>

#include "common/env/scenarios/registry.h"

namespace imca::env {
namespace {

// predator_prey (paper 5.2): the predators move first (simultaneously), then
// the prey takes a uniformly random action that fails if it would leave the
// prey zone or enter a wall or a predator. The prey is caught when each of its
// four neighbours is a predator, a wall or off the grid: every predator gets
// the success reward and the episode ends.
class PredatorPrey final : public Scenario {
 public:
  PredatorPrey(GridMap map, const ScenarioConfig& config, int n)
      : Scenario(std::move(map), config, n, 1, 5, 100, 20.0f, 0.0f) {}

  absl::string_view name() const override { return "predator_prey"; }
  int num_object_bits() const override { return 0; }

  void Reset(Rng& rng, int32_t* state) const override {
    state[kObjectsIndex] = 0;
    SpawnAgents(state + 1, rng);
    const auto& zone = map_.prey_zone();
    while (true) {
      const int32_t cell = zone[rng.Uniform(static_cast<uint32_t>(zone.size()))];
      bool free = true;
      for (int a = 0; a < num_agents_; ++a) free &= state[AgentIndex(a)] != cell;
      if (free) {
        state[1 + num_agents_] = cell;
        break;
      }
    }
    state[step_index()] = 0;
  }

  StepOutcome Step(int32_t* state, const int32_t* actions, Rng& rng, float* rewards) const override {
    const int t = StepAgents(state, actions, rng);
    int32_t& prey = state[1 + num_agents_];
    const int u = static_cast<int>(rng.Uniform(5));
    const int row = map_.Row(prey) + kActionRow[u], col = map_.Col(prey) + kActionCol[u];
    if (row >= 0 && row < map_.height() && col >= 0 && col < map_.width()) {
      const int cell = row * map_.width() + col;
      if (map_.InPreyZone(cell) && !map_.IsWall(cell) && !Occupied(state, cell)) prey = cell;
    }
    return Finish(t, Caught(state), rewards);
  }

 private:
  bool Occupied(const int32_t* state, int cell) const {
    for (int a = 0; a < num_agents_; ++a) {
      if (state[AgentIndex(a)] == cell) return true;
    }
    return false;
  }

  bool Caught(const int32_t* state) const {
    const int prey = state[1 + num_agents_];
    for (int u = 0; u < 4; ++u) {
      const int row = map_.Row(prey) + kActionRow[u], col = map_.Col(prey) + kActionCol[u];
      if (row < 0 || row >= map_.height() || col < 0 || col >= map_.width()) continue;
      const int cell = row * map_.width() + col;
      if (!map_.IsWall(cell) && !Occupied(state, cell)) return false;
    }
    return true;
  }
};

}  // namespace

// RND loses seeds here with coop_nav's bolder steps (two optimisers, lr
// 1e-3): it keeps the general defaults.
absl::Status RegisterPredatorPrey(ScenarioRegistry* registry) {
  return registry->Add(MakeScenarioEntry<PredatorPrey>(
      "predator_prey", 4, [](const GridMap& m) { return m.prey_zone().empty() ? "needs prey zone cells 'Z'" : ""; }));
}

}  // namespace imca::env
