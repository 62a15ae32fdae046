// Fuzzes the map-file parser: bytes -> GridMap::Parse; a map that parses is
// given to every scenario's rules (MakeScenarioWithMap), and a scenario that
// accepts it is stepped with actions taken from the input. Invariants:
// agents stand on cells of the map that are not walls.
#include <cstdint>
#include <string>
#include <vector>

#include "common/env/env.h"
#include "common/env/grid_map.h"
#include "common/env/vec_env.h"
#include "fuzz/fuzz_check.h"

using namespace imca;

extern "C" int LLVMFuzzerInitialize(int*, char***) { return 0; }

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  auto map = env::GridMap::Parse(text, "fuzz");
  if (!map.ok()) return 0;
  FUZZ_CHECK(map->width() > 0 && map->height() > 0);
  for (const std::string& name : env::ScenarioNames()) {
    env::ScenarioConfig config;
    config.name = name;
    config.step_limit = 16;
    auto scenario = env::MakeScenarioWithMap(config, *map);
    if (!scenario.ok()) continue;
    const env::Scenario& s = **scenario;
    const int n = s.num_agents(), E = 2, K = s.state_size();
    env::VecEnv envs(&s, E, /*seed=*/size);
    std::vector<int32_t> actions(E * n), reached(E * K);
    std::vector<float> rewards(E * n);
    bool terminated[E], truncated[E];
    for (int t = 0; t < 24; ++t) {
      for (int i = 0; i < E * n; ++i) {
        actions[i] = size > 0 ? data[(t * E * n + i) % size] % s.num_actions() : 0;
      }
      envs.Step(actions.data(), rewards.data(), terminated, truncated, reached.data());
      for (int e = 0; e < E; ++e) {
        for (int a = 0; a < n; ++a) {
          const int cell = envs.states()[e * K + env::AgentIndex(a)];
          FUZZ_CHECK(cell >= 0 && cell < s.map().num_cells() && !s.map().IsWall(cell));
        }
      }
    }
  }
  return 0;
}
