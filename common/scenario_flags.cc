#include "common/scenario_flags.h"

#include <string>

#include "absl/flags/flag.h"

ABSL_FLAG(std::string, scenario, "coop_nav", "scenario name");
ABSL_FLAG(std::string, map, "", "map file (default: maps/<scenario>.txt)");
ABSL_FLAG(int, num_agents, 0, "agents (0: scenario default)");
ABSL_FLAG(int, step_limit, 0, "episode step limit (0: scenario default)");

namespace imca {

absl::StatusOr<std::unique_ptr<env::Scenario>> ScenarioFromFlags() {
  env::ScenarioConfig config;
  config.name = absl::GetFlag(FLAGS_scenario);
  config.map_path = absl::GetFlag(FLAGS_map);
  config.num_agents = absl::GetFlag(FLAGS_num_agents);
  config.step_limit = absl::GetFlag(FLAGS_step_limit);
  return env::MakeScenario(config, env::DefaultMapDir());
}

}  // namespace imca
