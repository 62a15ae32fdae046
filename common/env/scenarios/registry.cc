#include "common/env/scenarios/registry.h"

#include "absl/strings/str_cat.h"

namespace imca::env {

const ScenarioRegistry& Scenarios() {
  static const ScenarioRegistry* const kRegistry = new ScenarioRegistry(BuildRegistry<ScenarioRegistry>({
#define IMCA_SCENARIO(Prefix) &Register##Prefix,
#include "common/env/scenarios/scenarios.def"
#undef IMCA_SCENARIO
  }));
  return *kRegistry;
}

std::string NeedDoors(const GridMap& map) {
  if (map.num_doors() == 0) return "needs at least one door 'A' with a switch 'a'";
  for (int d = 0; d < map.num_doors(); ++d) {
    if (map.switches(d).empty()) return absl::StrCat("door '", std::string(1, 'A' + d), "' has no switch");
  }
  return "";
}

std::string NeedTreasure(const GridMap& map, const char* what) {
  return map.treasures().empty() ? absl::StrCat("needs ", what) : "";
}

std::string NeedGoalMarker(const GridMap& map, const char* what) {
  return map.goal_markers().empty() ? absl::StrCat("needs ", what) : "";
}

}  // namespace imca::env
