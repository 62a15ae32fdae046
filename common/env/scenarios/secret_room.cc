#include <string>
#include <utility>

#include "common/env/scenarios/door_scenario.h"
#include "common/env/scenarios/registry.h"

namespace imca::env {
namespace {

class SecretRoom final : public DoorScenario {
 public:
  SecretRoom(GridMap map, const ScenarioConfig& config, int n)
      : DoorScenario(std::move(map), config, n, 4, 300, 1000.0f, 0.0f, 8, false, true) {}
  absl::string_view name() const override { return "secret_room"; }
};

}  // namespace

absl::Status RegisterSecretRoom(ScenarioRegistry* registry) {
  return registry->Add(MakeScenarioEntry<SecretRoom>("secret_room", 2, [](const GridMap& m) {
    const std::string goal = NeedGoalMarker(m, "a goal marker 'G' in the secret room");
    return goal.empty() ? NeedDoors(m) : goal;
  }));
}

}  // namespace imca::env
