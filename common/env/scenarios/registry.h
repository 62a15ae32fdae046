#ifndef IMCA_COMMON_ENV_SCENARIOS_REGISTRY_H_
#define IMCA_COMMON_ENV_SCENARIOS_REGISTRY_H_

#include <functional>
#include <memory>
#include <string>
#include <utility>

#include "absl/status/status.h"
#include "common/base/registry.h"
#include "common/env/env.h"
#include "common/env/grid_map.h"

namespace imca::env {

// The scenarios, each registered in its own file beside this one
// (coop_nav.cc, ...) by one line of scenarios.def, the one place that names
// them all (EnvPool's habit: the rules, the map check and the tuning beside
// each other, registered with one call). An entry carries everything the
// binaries and the tools know of a scenario.
struct ScenarioEntry {
  std::string name;        // --scenario; its map is maps/<name>.txt.
  int default_agents = 0;  // Agents when --num_agents is 0.
  // What the rules need of a map: "" if `map` has it, else what it lacks
  // ("needs a treasure 'T'").
  std::function<std::string(const GridMap& map)> check;
  // The scenario over `map` (checked) with `num_agents` agents (in range).
  std::function<std::unique_ptr<Scenario>(GridMap map, const ScenarioConfig& config, int num_agents)> make;
  // Where its training differs from the general defaults, and why (a
  // comment beside it).
  ScenarioTuning tuning;

  bool complete() const { return default_agents > 0 && check && make; }
};

// The registry (common/base/registry.h): Find's errors name --scenario.
class ScenarioRegistry : public Registry<ScenarioEntry> {
 public:
  ScenarioRegistry() : Registry("--scenario") {}
};

// Every scenario of scenarios.def, built on first use.
const ScenarioRegistry& Scenarios();

// The entry of scenario class T (constructed as T(map, config, num_agents)).
template <typename T>
ScenarioEntry MakeScenarioEntry(std::string name, int default_agents,
                                std::function<std::string(const GridMap& map)> check, ScenarioTuning tuning = {}) {
  return {std::move(name), default_agents, std::move(check),
          [](GridMap map, const ScenarioConfig& config, int n) -> std::unique_ptr<Scenario> {
            return std::make_unique<T>(std::move(map), config, n);
          },
          tuning};
}

// The entry of a scenario class T whose rules are data, so that one class
// serves several entries: constructed as T(name, rules, map, config,
// num_agents).
template <typename T, typename Rules>
ScenarioEntry MakeRulesEntry(std::string name, const Rules& rules, int default_agents,
                             std::function<std::string(const GridMap& map)> check, ScenarioTuning tuning = {}) {
  return {name, default_agents, std::move(check),
          [name, rules](GridMap map, const ScenarioConfig& config, int n) -> std::unique_ptr<Scenario> {
            return std::make_unique<T>(name, rules, std::move(map), config, n);
          },
          tuning};
}

// The map checks several scenarios share: "" or what the map lacks.
std::string NeedDoors(const GridMap& map);  // A door 'A' and a switch 'a' for each door.
std::string NeedTreasure(const GridMap& map, const char* what);  // A 'T' ("needs <what>").
std::string NeedGoalMarker(const GridMap& map, const char* what);  // A 'G' ("needs <what>").

// Each file's registration, one per line of scenarios.def.
#define IMCA_SCENARIO(Prefix) absl::Status Register##Prefix(ScenarioRegistry* registry);
#include "common/env/scenarios/scenarios.def"
#undef IMCA_SCENARIO

}  // namespace imca::env

#endif  // IMCA_COMMON_ENV_SCENARIOS_REGISTRY_H_
