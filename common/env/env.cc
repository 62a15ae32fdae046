#include "common/env/env.h"

#include <algorithm>
#include <cstdlib>
#include <cstring>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/env/scenarios/registry.h"

namespace imca::env {

Scenario::Scenario(GridMap map, const ScenarioConfig& config, int num_agents, int num_npcs,
                   int num_actions, int default_step_limit, float default_success_reward,
                   float default_step_penalty, bool agents_share_cells)
    : map_(std::move(map)),
      num_agents_(num_agents),
      num_npcs_(num_npcs),
      num_actions_(num_actions),
      step_limit_(config.step_limit > 0 ? config.step_limit : default_step_limit),
      view_radius_(config.view_radius),
      success_reward_(std::isnan(config.success_reward) ? default_success_reward
                                                        : static_cast<float>(config.success_reward)),
      step_penalty_(std::isnan(config.step_penalty) ? default_step_penalty
                                                    : static_cast<float>(config.step_penalty)),
      agents_share_cells_(agents_share_cells) {
  if (!agents_share_cells_) {
    spawn_pool_ = map_.random_spawns();
    return;
  }
  const std::vector<bool> rooms = map_.RoomOf(map_.random_spawns());
  for (int cell = 0; cell < map_.num_cells(); ++cell) {
    if (rooms[cell]) spawn_pool_.push_back(cell);
  }
}

uint64_t Scenario::fingerprint() const {
  uint64_t h = 0x8a5cd789635d2dffULL;
  auto mix = [&h](uint64_t x) {
    uint64_t s = h ^ (x + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2));
    h = Rng::SplitMix64(s);
  };
  for (char c : name()) mix(static_cast<uint8_t>(c));
  for (int v : {map_.width(), map_.height(), num_agents_, num_npcs_, num_actions_, step_limit_, view_radius_,
                door_timer() + 1, static_cast<int>(agents_share_cells_)}) {
    mix(v);
  }
  uint32_t bits;
  std::memcpy(&bits, &success_reward_, 4);
  mix(bits);
  std::memcpy(&bits, &step_penalty_, 4);
  mix(bits);
  for (int cell = 0; cell < map_.num_cells(); ++cell) {
    mix(static_cast<uint64_t>(map_.IsWall(cell)) | static_cast<uint64_t>(map_.InPreyZone(cell)) << 1 |
        static_cast<uint64_t>(map_.DoorAt(cell) + 1) << 2 | static_cast<uint64_t>(map_.SwitchAt(cell) + 1) << 8);
  }
  for (const auto* cells : {&map_.treasures(), &map_.buttons(), &map_.goal_markers(), &map_.random_spawns(),
                            &map_.box_centres()}) {
    mix(cells->size());
    for (int32_t cell : *cells) mix(cell);
  }
  for (int a = 0; a < num_agents_; ++a) mix(static_cast<uint64_t>(map_.FixedSpawn(a) + 1));
  return h == 0 ? 1 : h;
}

bool Scenario::ButtonPressed(const int32_t* state, int button) const {
  const int32_t cell = map_.buttons()[button];
  for (int a = 0; a < num_agents_; ++a) {
    if (state[AgentIndex(a)] == cell) return true;
  }
  return false;
}

bool Scenario::Enterable(const int32_t* state, int cell) const {
  if (map_.IsWall(cell)) return false;
  const int door = map_.DoorAt(cell);
  return door < 0 || DoorOpen(state, door);
}

void Scenario::MoveAgents(const int32_t* state, int32_t* cells, int count, const int32_t* actions,
                          const int32_t* others, int num_others, Rng& rng) const {
  const int width = map_.width();
  int32_t target[kMaxAgents];
  for (int a = 0; a < count; ++a) {
    const int u = actions[a];
    const int row = map_.Row(cells[a]) + kActionRow[u];
    const int col = map_.Col(cells[a]) + kActionCol[u];
    target[a] = cells[a];
    if (row < 0 || row >= map_.height() || col < 0 || col >= width) continue;
    const int cell = row * width + col;
    if (!Enterable(state, cell)) continue;
    bool taken = false;
    for (int j = 0; j < num_others; ++j) taken |= others[j] == cell;
    if (!taken) target[a] = cell;
  }
  if (agents_share_cells_) {
    for (int a = 0; a < count; ++a) cells[a] = target[a];
    return;
  }
  bool contested = false;
  for (int a = 0; a < count && !contested; ++a) {
    for (int b = a + 1; b < count; ++b) {
      if (target[a] == target[b] && target[a] != cells[a] && target[b] != cells[b]) contested = true;
    }
  }
  // rank[a] < rank[b]: a wins a contested cell. Drawn only when needed, so
  // uncontested steps consume no randomness.
  int rank[kMaxAgents];
  for (int a = 0; a < count; ++a) rank[a] = a;
  if (contested) {
    for (int a = count - 1; a > 0; --a) std::swap(rank[a], rank[rng.Uniform(a + 1)]);
  }
  bool changed = true;
  while (changed) {
    changed = false;
    for (int a = 0; a < count; ++a) {
      if (target[a] == cells[a]) continue;
      for (int b = 0; b < count; ++b) {
        if (b == a) continue;
        const bool b_stays = target[b] == cells[b];
        const bool into_staying = target[a] == cells[b] && b_stays;
        const bool swap = target[a] == cells[b] && target[b] == cells[a];
        const bool loses = target[a] == target[b] && !b_stays && rank[b] < rank[a];
        if (into_staying || swap || loses) {
          target[a] = cells[a];
          changed = true;
          break;
        }
      }
    }
  }
  for (int a = 0; a < count; ++a) cells[a] = target[a];
}

int Scenario::StepAgents(int32_t* state, const int32_t* actions, Rng& rng) const {
  MoveAgents(state, state + 1, num_agents_, actions, state + 1 + num_agents_, num_npcs_, rng);
  return ++state[step_index()];
}

void Scenario::Reset(Rng& rng, int32_t* state) const {
  state[kObjectsIndex] = 0;
  SpawnAgents(state + 1, rng);
  state[step_index()] = 0;
}

StepOutcome Scenario::Finish(int t, bool success, float* rewards) const {
  StepOutcome outcome;
  outcome.success = success;
  outcome.terminated = success;
  outcome.truncated = !success && t >= step_limit_;
  const float reward = -step_penalty_ + (success ? success_reward_ : 0.0f);
  for (int a = 0; a < num_agents_; ++a) rewards[a] = reward;
  return outcome;
}

void Scenario::SpawnAgents(int32_t* cells, Rng& rng) const {
  const auto& pool = spawn_pool_;
  int32_t taken[kMaxAgents];
  int num_taken = 0;
  for (int a = 0; a < num_agents_; ++a) {
    const int fixed = map_.FixedSpawn(a);
    if (fixed >= 0) {
      cells[a] = fixed;
      continue;
    }
    if (agents_share_cells_) {
      cells[a] = pool[rng.Uniform(static_cast<uint32_t>(pool.size()))];
      continue;
    }
    // Rejection sampling over the pool; MakeScenario guarantees enough cells.
    while (true) {
      const int32_t cell = pool[rng.Uniform(static_cast<uint32_t>(pool.size()))];
      bool free = true;
      for (int i = 0; i < num_taken; ++i) free &= taken[i] != cell;
      for (int b = 0; b < num_agents_; ++b) free &= map_.FixedSpawn(b) != cell;
      if (free) {
        cells[a] = cell;
        taken[num_taken++] = cell;
        break;
      }
    }
  }
}

absl::Status Scenario::ValidateState(const int32_t* state) const {
  const int64_t z = state[kObjectsIndex];
  if (z < 0 || (num_object_bits() < 31 && z >= (int64_t{1} << num_object_bits()))) {
    return absl::InvalidArgumentError(absl::StrCat("object bits ", z, " out of range for ", name()));
  }
  for (int i = 0; i < num_agents_ + num_npcs_; ++i) {
    const int32_t cell = state[1 + i];
    const std::string who = i < num_agents_ ? absl::StrCat("agent ", i) : absl::StrCat("entity ", i - num_agents_);
    if (cell < 0 || cell >= map_.num_cells() || map_.IsWall(cell)) {
      return absl::InvalidArgumentError(
          absl::StrCat("cell of ", who, " is ", cell, ", not a floor cell of the map"));
    }
    // Agents that may share a cell may share it; entities never.
    const bool may_share = agents_share_cells_ && i < num_agents_;
    for (int j = 0; j < i && !may_share; ++j) {
      if (state[1 + j] == cell) {
        return absl::InvalidArgumentError(absl::StrCat("cell of ", who, " is ", cell, ", already taken"));
      }
    }
  }
  const int32_t t = state[step_index()];
  if (t < 0 || t > step_limit_) {
    return absl::InvalidArgumentError(absl::StrCat("step count ", t, " outside [0, ", step_limit_, "]"));
  }
  return absl::OkStatus();
}

std::string Scenario::Render(const int32_t* state) const {
  std::string out;
  const auto& treasures = map_.treasures();
  for (int row = 0; row < map_.height(); ++row) {
    for (int col = 0; col < map_.width(); ++col) {
      const int cell = row * map_.width() + col;
      char c = map_.IsWall(cell) ? '#' : (map_.InPreyZone(cell) ? 'Z' : '.');
      for (int32_t g : map_.goal_markers()) c = g == cell ? 'G' : c;
      for (int32_t b : map_.buttons()) c = b == cell ? 'X' : c;
      for (size_t k = 0; k < treasures.size(); ++k) {
        if (treasures[k] == cell && !TreasureCollected(state, static_cast<int>(k))) c = 'T';
      }
      if (map_.SwitchAt(cell) == GridMap::kEveryDoor) {
        c = '*';
      } else if (map_.SwitchAt(cell) >= 0) {
        c = static_cast<char>('a' + map_.SwitchAt(cell));
      }
      if (map_.DoorAt(cell) >= 0) c = DoorOpen(state, map_.DoorAt(cell)) ? '/' : static_cast<char>('A' + map_.DoorAt(cell));
      for (int j = 0; j < num_npcs_; ++j) c = Covers(state, j, cell) ? EntityChar() : c;
      for (int a = num_agents_ - 1; a >= 0; --a) c = state[AgentIndex(a)] == cell ? static_cast<char>('1' + a) : c;
      out.push_back(c);
    }
    out.push_back('\n');
  }
  absl::StrAppend(&out, "t=", state[step_index()], " z=", state[kObjectsIndex], "\n");
  return out;
}

std::vector<std::string> ScenarioNames() { return Scenarios().Names(); }

const ScenarioTuning& TuningOf(absl::string_view name) {
  static const ScenarioTuning kNone;
  absl::StatusOr<const ScenarioEntry*> entry = Scenarios().Find(name);
  return entry.ok() && !name.empty() ? (*entry)->tuning : kNone;
}

absl::StatusOr<std::unique_ptr<Scenario>> MakeScenario(const ScenarioConfig& config,
                                                       const std::string& map_dir) {
  IMCA_RETURN_IF_ERROR(Scenarios().Find(config.name).status());
  const std::string path =
      config.map_path.empty() ? absl::StrCat(map_dir, "/", config.name, ".txt") : config.map_path;
  absl::StatusOr<GridMap> map = GridMap::Load(path);
  if (!map.ok()) return map.status();
  return MakeScenarioWithMap(config, *std::move(map));
}

absl::StatusOr<std::unique_ptr<Scenario>> MakeScenarioWithMap(const ScenarioConfig& config,
                                                              GridMap map) {
  if (config.name.empty()) return absl::InvalidArgumentError("--scenario: a scenario needs a name");
  IMCA_ASSIGN_OR_RETURN(const ScenarioEntry* entry, Scenarios().Find(config.name));
  if (config.num_agents < 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("num_agents ", config.num_agents, " is negative (0: the scenario's default)"));
  }
  const int num_agents = config.num_agents > 0 ? config.num_agents : entry->default_agents;
  if (num_agents > kMaxAgents) {
    return absl::InvalidArgumentError(absl::StrCat("num_agents ", num_agents, " above ", kMaxAgents));
  }
  if (const std::string problem = entry->check(map); !problem.empty()) {
    return absl::InvalidArgumentError(absl::StrCat(map.source(), ": ", config.name, " ", problem));
  }
  if (config.door_timer < -1 || config.door_timer > kMaxDoorTimer) {
    return absl::InvalidArgumentError(
        absl::StrCat("door_timer ", config.door_timer, " not in [0, ", kMaxDoorTimer, "]"));
  }
  if (config.step_limit < 0 || config.step_limit > 100000) {
    return absl::InvalidArgumentError(absl::StrCat("step_limit ", config.step_limit, " not in [1, 100000]"));
  }
  if (config.view_radius < 0) {
    return absl::InvalidArgumentError(absl::StrCat("view_radius ", config.view_radius, " is negative"));
  }
  if (!std::isnan(config.success_reward) && !std::isfinite(config.success_reward)) {
    return absl::InvalidArgumentError("success_reward must be finite");
  }
  if (!std::isnan(config.step_penalty) && !std::isfinite(config.step_penalty)) {
    return absl::InvalidArgumentError("step_penalty must be finite");
  }
  const std::string source = map.source();
  std::unique_ptr<Scenario> scenario = entry->make(std::move(map), config, num_agents);
  if (config.door_timer >= 0 && scenario->door_timer() < 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("door_timer is for the timed door scenarios (multi_room, pass, secret_room), not ",
                     config.name));
  }
  if (scenario->map().shared_spawn() >= 0 && !scenario->agents_share_cells()) {
    return absl::InvalidArgumentError(absl::StrCat(
        source, ": '@' starts every agent on one cell, but ", config.name, "'s agents cannot share a cell"));
  }
  int random_needed = 0;
  for (int a = 0; a < num_agents; ++a) random_needed += scenario->map().FixedSpawn(a) < 0;
  const int pool = static_cast<int>(scenario->spawn_pool().size());
  if (random_needed > 0 && (scenario->agents_share_cells() ? pool == 0 : random_needed > pool)) {
    return absl::InvalidArgumentError(absl::StrCat(source, ": ", random_needed,
                                                   " agents need a random spawn but the map has ",
                                                   scenario->map().random_spawns().size(), " 'S' cells"));
  }
  return scenario;
}

std::string DefaultMapDir() {
  if (const char* dir = std::getenv("IMCA_MAP_DIR")) return dir;
  return IMCA_SOURCE_DIR "/maps";
}

}  // namespace imca::env
