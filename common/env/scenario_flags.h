#ifndef IMCA_COMMON_ENV_SCENARIO_FLAGS_H_
#define IMCA_COMMON_ENV_SCENARIO_FLAGS_H_

#include <memory>

#include "absl/status/statusor.h"
#include "common/env/env.h"

namespace imca {

// The scenario flags every binary shares: --scenario, --map, --num_agents,
// --step_limit, --success_reward, --step_penalty, --view_radius, --door_timer. Call after absl::ParseCommandLine. Errors: those of
// env::MakeScenario (the message names the map file or the scenario).
absl::StatusOr<std::unique_ptr<env::Scenario>> ScenarioFromFlags();

}  // namespace imca

#endif  // IMCA_COMMON_ENV_SCENARIO_FLAGS_H_
