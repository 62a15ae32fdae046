#include <string>
#include <utility>

#include "common/env/scenarios/door_scenario.h"
#include "common/env/scenarios/registry.h"

namespace imca::env {
namespace {

// EDTI's Pass and ThreePass (docs/scenarios.md, "pass and secret_room"): 4 actions, agents move
// independently and may share a cell, doi 8 (the default of EDTI's code).
class Pass final : public DoorScenario {
 public:
  Pass(GridMap map, const ScenarioConfig& config, int n)
      : DoorScenario(std::move(map), config, n, 4, 300, 1000.0f, 0.0f, 8, false, true) {}
  absl::string_view name() const override { return "pass"; }
};

}  // namespace

absl::Status RegisterPass(ScenarioRegistry* registry) {
  return registry->Add(MakeScenarioEntry<Pass>("pass", 2, [](const GridMap& m) {
    const std::string goal = NeedGoalMarker(m, "a goal marker 'G' in the far room");
    return goal.empty() ? NeedDoors(m) : goal;
  }));
}

}  // namespace imca::env
