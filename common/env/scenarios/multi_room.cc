#include <string>
#include <utility>

#include "common/env/scenarios/door_scenario.h"
#include "common/env/scenarios/registry.h"

namespace imca::env {
namespace {

class MultiRoom final : public DoorScenario {
 public:
  MultiRoom(GridMap map, const ScenarioConfig& config, int n)
      : DoorScenario(std::move(map), config, n, 5, 300, 50.0f, 0.1f, 0, true, false) {}
  absl::string_view name() const override { return "multi_room"; }
};

}  // namespace

absl::Status RegisterMultiRoom(ScenarioRegistry* registry) {
  return registry->Add(MakeScenarioEntry<MultiRoom>("multi_room", 2, [](const GridMap& m) {
    const std::string treasure = NeedTreasure(m, "a treasure 'T' in the last room");
    return treasure.empty() ? NeedDoors(m) : treasure;
  }));
}

}  // namespace imca::env
