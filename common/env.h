#ifndef IMCA_COMMON_ENV_H_
#define IMCA_COMMON_ENV_H_

#include <cstdint>
#include <memory>
#include <string>
#include "absl/strings/string_view.h"

#include "absl/status/statusor.h"
#include "common/grid_map.h"
#include "common/rng.h"

namespace imca::env {

// Actions shared by every 5-action scenario.
enum Action : int32_t { kUp = 0, kDown = 1, kLeft = 2, kRight = 3, kStay = 4 };
inline constexpr int kNumMoveActions = 5;
inline constexpr int kMaxAgents = 9;

// The compact state of one environment, as it travels in Unroll.states:
//   state[0]        = z, the shared object bits (scenario-defined; coop_nav:
//                     bit k set when treasure k has been collected)
//   state[1 + a]    = cell of agent a (row * width + col)
//   state[1 + n]    = step count t within the episode
// state_size = n + 2.
inline constexpr int kObjectsIndex = 0;
inline int AgentIndex(int agent) { return 1 + agent; }

struct ScenarioConfig {
  std::string name = "coop_nav";
  std::string map_path;  // Empty: maps/<name>.txt under the map directory.
  int num_agents = 0;    // 0: the scenario default.
  int step_limit = 0;    // 0: the scenario default.
};

struct StepOutcome {
  bool terminated = false;  // Episode over, no bootstrap (success or failure).
  bool truncated = false;   // Step limit reached without termination.
  bool success = false;
};

// A gridworld scenario: the rules over a GridMap. Stateless: all episode state
// is in the caller's int32 array, so one Scenario serves any number of
// environments. Immutable after creation; thread-safe.
class Scenario {
 public:
  virtual ~Scenario() = default;

  virtual absl::string_view name() const = 0;
  int num_agents() const { return num_agents_; }
  int num_actions() const { return num_actions_; }
  int state_size() const { return num_agents_ + 2; }
  int step_limit() const { return step_limit_; }
  // Number of meaningful low bits of z (objects).
  virtual int num_object_bits() const = 0;
  const GridMap& map() const { return map_; }

  // Writes a fresh initial state into state[0..state_size).
  virtual void Reset(Rng& rng, int32_t* state) const = 0;
  // Applies the joint action (actions[0..n), each in [0, num_actions)) to
  // `state` in place and writes each agent's extrinsic reward.
  virtual StepOutcome Step(int32_t* state, const int32_t* actions, Rng& rng,
                           float* rewards) const = 0;

  // OK if `state` could occur in this scenario: cells in range and not walls,
  // z within num_object_bits, t within [0, step_limit]. The error message
  // names the offending element, e.g. "cell of agent 1".
  absl::Status ValidateState(const int32_t* state) const;

  // Multi-line text picture: '#' wall, 'T' uncollected treasure, '1'.. agents.
  std::string Render(const int32_t* state) const;

 protected:
  Scenario(GridMap map, int num_agents, int num_actions, int step_limit)
      : map_(std::move(map)), num_agents_(num_agents), num_actions_(num_actions),
        step_limit_(step_limit) {}

  // Simultaneous moves of all agents (cells updated in place): a move into a
  // wall or off the grid fails; agents never share a cell or swap places; when
  // several agents want the same cell, a random priority order drawn from
  // `rng` decides which one gets it. Agents that fail stay where they are.
  void MoveAgents(int32_t* cells, const int32_t* actions, Rng& rng) const;
  // Places agents at their fixed spawns or on distinct random spawn cells.
  void SpawnAgents(int32_t* cells, Rng& rng) const;

  GridMap map_;
  int num_agents_;
  int num_actions_;
  int step_limit_;
};

// Creates a scenario by name, loading its map (config.map_path or
// <map_dir>/<name>.txt). Errors: INVALID_ARGUMENT for an unknown scenario, an
// agent count the map cannot hold or a bad step limit; NOT_FOUND / INVALID_ARGUMENT
// from the map loader.
absl::StatusOr<std::unique_ptr<Scenario>> MakeScenario(const ScenarioConfig& config,
                                                       const std::string& map_dir);

// As MakeScenario, with an already parsed map (config.map_path is ignored).
absl::StatusOr<std::unique_ptr<Scenario>> MakeScenarioWithMap(const ScenarioConfig& config,
                                                              GridMap map);

// The directory holding the bundled maps: $IMCA_MAP_DIR, else the source tree's maps/.
std::string DefaultMapDir();

}  // namespace imca::env

#endif  // IMCA_COMMON_ENV_H_
