#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "common/env/scenarios/registry.h"

namespace imca::env {
namespace {

// spread (MPE's simple_spread on a grid): every step each agent receives
// minus the sum, over the landmarks (the map's treasures), of the Euclidean
// distance between the landmark's cell and its nearest agent's. No episode
// ends early; success means every landmark covered at the last step.
class Spread final : public Scenario {
 public:
  Spread(GridMap map, const ScenarioConfig& config, int n)
      : Scenario(std::move(map), config, n, 0, 5, 25, 0.0f, 0.0f) {}

  absl::string_view name() const override { return "spread"; }
  int num_object_bits() const override { return 0; }  // Landmarks are never used up.

  StepOutcome Step(int32_t* state, const int32_t* actions, Rng& rng, float* rewards) const override {
    const int t = StepAgents(state, actions, rng);
    double cost = 0;
    bool covered = true;
    for (int32_t landmark : map_.treasures()) {
      double nearest = std::numeric_limits<double>::infinity();
      for (int a = 0; a < num_agents_; ++a) {
        const int32_t cell = state[AgentIndex(a)];
        const double dr = map_.Row(cell) - map_.Row(landmark), dc = map_.Col(cell) - map_.Col(landmark);
        nearest = std::min(nearest, std::sqrt(dr * dr + dc * dc));
      }
      cost += nearest;
      covered &= nearest == 0;
    }
    for (int a = 0; a < num_agents_; ++a) rewards[a] = static_cast<float>(-cost);
    StepOutcome outcome;
    outcome.truncated = t >= step_limit_;
    outcome.success = outcome.truncated && covered;
    return outcome;
  }
};

}  // namespace

absl::Status RegisterSpread(ScenarioRegistry* registry) {
  return registry->Add(MakeScenarioEntry<Spread>(
      "spread", 3, [](const GridMap& m) { return NeedTreasure(m, "at least one landmark 'T'"); }));
}

}  // namespace imca::env
