#include "common/env/scenario_flags.h"

#include <cmath>
#include <string>

#include "absl/flags/flag.h"

ABSL_FLAG(std::string, scenario, imca::env::ScenarioConfig{}.name, "scenario name");
ABSL_FLAG(std::string, map, "", "map file (default: maps/<scenario>.txt)");
ABSL_FLAG(int, num_agents, 0, "agents (0: scenario default)");
ABSL_FLAG(int, step_limit, 0, "episode step limit (0: scenario default)");
ABSL_FLAG(double, success_reward, std::nan(""), "reward to each agent on success (default: the scenario's)");
ABSL_FLAG(double, step_penalty, std::nan(""), "cost to each agent per step (default: the scenario's)");
ABSL_FLAG(int, view_radius, 0, "partial observation: see others within this many cells (0: everything)");
ABSL_FLAG(int, door_timer, -1,
          "door scenarios: EDTI's door-open interval doi, a door passes doi + 1 moves after it opens "
          "(-1: the scenario default, 0 for multi_room, 8 for pass and secret_room)");

namespace imca {

absl::StatusOr<std::unique_ptr<env::Scenario>> ScenarioFromFlags() {
  env::ScenarioConfig config;
  config.name = absl::GetFlag(FLAGS_scenario);
  config.map_path = absl::GetFlag(FLAGS_map);
  config.num_agents = absl::GetFlag(FLAGS_num_agents);
  config.step_limit = absl::GetFlag(FLAGS_step_limit);
  config.success_reward = absl::GetFlag(FLAGS_success_reward);
  config.step_penalty = absl::GetFlag(FLAGS_step_penalty);
  config.view_radius = absl::GetFlag(FLAGS_view_radius);
  config.door_timer = absl::GetFlag(FLAGS_door_timer);
  return env::MakeScenario(config, env::DefaultMapDir());
}

}  // namespace imca
