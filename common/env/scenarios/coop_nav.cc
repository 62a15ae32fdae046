#include <cstdint>
#include <utility>

#include "common/env/scenarios/registry.h"

namespace imca::env {
namespace {

// coop_nav (paper 5.1): collect every treasure; an agent collects one by
// stepping on it. z bit k: treasure k collected.
class CoopNav final : public Scenario {
 public:
  CoopNav(GridMap map, const ScenarioConfig& config, int n)
      : Scenario(std::move(map), config, n, 0, 5, 100, 50.0f, 0.1f),
        all_collected_((1u << map_.treasures().size()) - 1) {}

  absl::string_view name() const override { return "coop_nav"; }
  int num_object_bits() const override { return static_cast<int>(map_.treasures().size()); }
  bool TreasureCollected(const int32_t* state, int k) const override {
    return (static_cast<uint32_t>(state[kObjectsIndex]) >> k) & 1u;
  }

  StepOutcome Step(int32_t* state, const int32_t* actions, Rng& rng, float* rewards) const override {
    const int t = StepAgents(state, actions, rng);
    uint32_t z = static_cast<uint32_t>(state[kObjectsIndex]);
    const auto& treasures = map_.treasures();
    for (int a = 0; a < num_agents_; ++a) {
      for (size_t k = 0; k < treasures.size(); ++k) {
        if (state[AgentIndex(a)] == treasures[k]) z |= 1u << k;
      }
    }
    state[kObjectsIndex] = static_cast<int32_t>(z);
    return Finish(t, z == all_collected_, rewards);
  }

 private:
  uint32_t all_collected_;
};

}  // namespace

// Two optimisers (an Adam and a grad clip each for actor and critic), 2048
// env steps per iteration and lr 1e-3: measured against the general defaults
// in docs/benchmarks.md ("The new defaults"); 64-step unrolls, each env's
// whole share of an iteration (2 actors x 16 envs), as the reference MAPPO
// collects (docs/learner.md, "Defaults").
absl::Status RegisterCoopNav(ScenarioRegistry* registry) {
  return registry->Add(MakeScenarioEntry<CoopNav>(
      "coop_nav", 2, [](const GridMap& m) { return NeedTreasure(m, "at least one treasure 'T'"); },
      {/*batch_steps=*/2048, /*learning_rate=*/1e-3, /*separate_optimizers=*/true, /*unroll_length=*/64,
       /*bonus_scale=*/{}}));
}

}  // namespace imca::env
