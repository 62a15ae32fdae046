#ifndef IMCA_COMMON_ENV_ENV_H_
#define IMCA_COMMON_ENV_ENV_H_

#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "common/base/rng.h"
#include "common/env/grid_map.h"

namespace imca::env {

// Actions. Scenarios with 4 actions (pass) use the first four (no stay).
enum Action : int32_t { kUp = 0, kDown = 1, kLeft = 2, kRight = 3, kStay = 4 };
// The cell offsets of each action: row, column.
inline constexpr int kActionRow[5] = {-1, 1, 0, 0, 0};
inline constexpr int kActionCol[5] = {0, 0, -1, 1, 0};
inline constexpr int kMaxAgents = 9;
inline constexpr int kMaxNpcs = 4;

// The compact state of one environment, as it travels in Unroll.states, K =
// n + m + 2 int32 values (n agents, m non-player entities such as the prey):
//   state[0]          z, the scenario's object bits (docs/scenarios.md)
//   state[1 + a]      cell of agent a (row * width + col)
//   state[1 + n + j]  cell of entity j (predator_prey: the prey)
//   state[1 + n + m]  step count t within the episode
inline constexpr int kObjectsIndex = 0;
inline int AgentIndex(int agent) { return 1 + agent; }

struct ScenarioConfig {
  std::string name = "coop_nav";
  std::string map_path;  // Empty: <map_dir>/<name>.txt.
  int num_agents = 0;    // 0: the scenario default.
  int step_limit = 0;    // 0: the scenario default.
  // NaN: the scenario default (docs/scenarios.md).
  double success_reward = std::nan("");
  double step_penalty = std::nan("");
  int view_radius = 0;   // predator_prey: 0 = full observation, r = see others within r cells.
  // Door scenarios (multi_room, pass, secret_room): EDTI's door-open interval
  // `doi` (docs/scenarios.md, "Doors"), at most kMaxDoorTimer; -1: the
  // scenario default.
  int door_timer = -1;
};

// Largest door_timer (a door's state holds the count).
inline constexpr int kMaxDoorTimer = 30;

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
  int num_npcs() const { return num_npcs_; }
  int num_actions() const { return num_actions_; }
  int state_size() const { return num_agents_ + num_npcs_ + 2; }
  int step_index() const { return 1 + num_agents_ + num_npcs_; }
  int step_limit() const { return step_limit_; }
  int view_radius() const { return view_radius_; }
  // True if agents move independently and may share a cell (EDTI's pass and
  // secret_room); false: moves are resolved so that no two agents share one.
  bool agents_share_cells() const { return agents_share_cells_; }
  // Door scenarios: EDTI's door-open interval; -1 elsewhere.
  virtual int door_timer() const { return -1; }
  // Where agents without a fixed spawn start: the 'S' cells or, if agents may
  // share a cell, every floor cell of the rooms holding an 'S'.
  const std::vector<int32_t>& spawn_pool() const { return spawn_pool_; }
  float success_reward() const { return success_reward_; }
  float step_penalty() const { return step_penalty_; }
  // A hash of the map layout and the rules (name, agents, entities, actions,
  // step limit, rewards, view radius, door timer, shared cells; the spawn pool
  // follows from those): two processes with equal fingerprints play the same
  // game. Never 0.
  uint64_t fingerprint() const;
  // Number of meaningful low bits of z.
  virtual int num_object_bits() const = 0;
  const GridMap& map() const { return map_; }

  // Writes a fresh initial state into state[0..state_size). By default:
  // no object bits, the agents spawned (SpawnAgents), step 0.
  virtual void Reset(Rng& rng, int32_t* state) const;
  // Applies the joint action (actions[0..n), each in [0, num_actions)) to
  // `state` in place and writes each agent's extrinsic reward.
  virtual StepOutcome Step(int32_t* state, const int32_t* actions, Rng& rng,
                           float* rewards) const = 0;

  // What a state shows, for renderers and tests.
  virtual bool DoorOpen(const int32_t* state, int door) const { return false; }
  virtual bool TreasureCollected(const int32_t* state, int treasure) const { return false; }
  // Whether non-player entity `entity` covers `cell` (its own cell, or the
  // 3x3 box of push_box_cmae), and the character Render draws it with.
  virtual bool Covers(const int32_t* state, int entity, int cell) const {
    return state[1 + num_agents_ + entity] == cell;
  }
  virtual char EntityChar() const { return 'P'; }
  // A button is pressed while an agent stands on it.
  bool ButtonPressed(const int32_t* state, int button) const;

  // OK if `state` could occur in this scenario: cells in range and not walls,
  // no two agents on one cell (unless agents_share_cells()) and no agent on
  // an entity, z within num_object_bits, t within [0, step_limit]. The error
  // message names the offending element, e.g. "cell of agent 1".
  absl::Status ValidateState(const int32_t* state) const;

  // Multi-line text picture (docs/scenarios.md legend; agents '1'.., the prey 'P',
  // an open door '/', a collected treasure or pressed button shown as floor
  // or as the agent on it), then "t=.. z=..".
  std::string Render(const int32_t* state) const;

 protected:
  Scenario(GridMap map, const ScenarioConfig& config, int num_agents, int num_npcs, int num_actions,
           int default_step_limit, float default_success_reward, float default_step_penalty,
           bool agents_share_cells = false);

  // True if an agent or entity may enter `cell` given the doors of `state`.
  bool Enterable(const int32_t* state, int cell) const;
  // Simultaneous moves of `count` movers (cells updated in place): a move into
  // a wall, a closed door, `others` (cells of non-movers) or off the grid
  // fails. Unless agents share cells, movers never share a cell or swap
  // places; when several want the same cell, a random priority order drawn
  // from `rng` (only on such steps) decides and the others stay.
  void MoveAgents(const int32_t* state, int32_t* cells, int count, const int32_t* actions,
                  const int32_t* others, int num_others, Rng& rng) const;
  // Places agents at their fixed spawns or on random cells of spawn_pool():
  // distinct cells, or independent draws if agents share cells.
  void SpawnAgents(int32_t* cells, Rng& rng) const;
  // Moves the agents of `state` with `actions`, increments t. Returns new t.
  int StepAgents(int32_t* state, const int32_t* actions, Rng& rng) const;
  // Fills rewards with the step penalty (+ success reward) and the outcome
  // flags from `success` and the step limit.
  StepOutcome Finish(int t, bool success, float* rewards) const;

  GridMap map_;
  int num_agents_;
  int num_npcs_;
  int num_actions_;
  int step_limit_;
  int view_radius_;
  float success_reward_;
  float step_penalty_;
  bool agents_share_cells_;
  std::vector<int32_t> spawn_pool_;
};

// Names of the available scenarios (common/env/scenarios/scenarios.def), in
// alphabetical order.
std::vector<std::string> ScenarioNames();

// Where a scenario's training differs from the components' general defaults
// (LearnerConfig, PpoConfig, ActorConfig, reward::ScorerConfig): EnvPool's
// per-env default config, in the scenario's registry entry (common/env/scenarios/,
// beside its rules). Unset fields take the general default; flags given by a
// user win over both (DefaultLearnerConfig, DefaultActorConfig,
// reward::DefaultScorerConfig resolve them). docs/learner.md, "Defaults",
// has how each was measured.
struct ScenarioTuning {
  std::optional<int64_t> batch_steps;        // LearnerConfig::batch_steps.
  std::optional<double> learning_rate;       // PpoConfig::learning_rate.
  std::optional<bool> separate_optimizers;   // PpoConfig::separate_optimizers.
  std::optional<int> unroll_length;          // ActorConfig::unroll_length.
  // Multiplies the reward server's default beta of every reward kind
  // (reward::DefaultScorerConfig): the intrinsic bonus at the scale of the
  // task's own reward where that differs from the scale the defaults were
  // measured at. Keyed by the scenario, not its --success_reward.
  std::optional<double> bonus_scale;
};

// The tuning of scenario `name` (an unknown name: none, all general defaults).
const ScenarioTuning& TuningOf(absl::string_view name);

// Creates a scenario by name, loading its map (config.map_path or
// <map_dir>/<name>.txt). Errors: INVALID_ARGUMENT for an unknown scenario, an
// agent count the map cannot hold, a map lacking what the scenario needs, a
// bad step limit, or a door timer out of [0, 30] or given to a scenario
// without doors; NOT_FOUND / INVALID_ARGUMENT from the map loader.
absl::StatusOr<std::unique_ptr<Scenario>> MakeScenario(const ScenarioConfig& config,
                                                       const std::string& map_dir);

// As MakeScenario, with an already parsed map (config.map_path is ignored).
absl::StatusOr<std::unique_ptr<Scenario>> MakeScenarioWithMap(const ScenarioConfig& config,
                                                              GridMap map);

// The directory holding the bundled maps: $IMCA_MAP_DIR, else the source tree's maps/.
std::string DefaultMapDir();

}  // namespace imca::env

#endif  // IMCA_COMMON_ENV_ENV_H_
