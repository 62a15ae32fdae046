#include <cstdint>
#include <utility>

#include "common/env/scenarios/registry.h"

namespace imca::env {
namespace {

// twin_buttons (paper fig. 1b): success when every button is pressed on the
// same step. z bit k: button k pressed after the last step.
class TwinButtons final : public Scenario {
 public:
  TwinButtons(GridMap map, const ScenarioConfig& config, int n)
      : Scenario(std::move(map), config, n, 0, 5, 100, 50.0f, 0.1f) {}

  absl::string_view name() const override { return "twin_buttons"; }
  int num_object_bits() const override { return static_cast<int>(map_.buttons().size()); }

  void Reset(Rng& rng, int32_t* state) const override {
    SpawnAgents(state + 1, rng);
    state[step_index()] = 0;
    state[kObjectsIndex] = static_cast<int32_t>(Pressed(state));
  }

  StepOutcome Step(int32_t* state, const int32_t* actions, Rng& rng, float* rewards) const override {
    const int t = StepAgents(state, actions, rng);
    const uint32_t pressed = Pressed(state);
    state[kObjectsIndex] = static_cast<int32_t>(pressed);
    return Finish(t, pressed == (1u << map_.buttons().size()) - 1, rewards);
  }

 private:
  uint32_t Pressed(const int32_t* state) const {
    uint32_t z = 0;
    for (size_t k = 0; k < map_.buttons().size(); ++k) {
      if (ButtonPressed(state, static_cast<int>(k))) z |= 1u << k;
    }
    return z;
  }
};

}  // namespace

absl::Status RegisterTwinButtons(ScenarioRegistry* registry) {
  return registry->Add(MakeScenarioEntry<TwinButtons>(
      "twin_buttons", 2, [](const GridMap& m) { return m.buttons().empty() ? "needs buttons 'X'" : ""; }));
}

}  // namespace imca::env
