#include "common/env.h"

#include <cstdlib>

#include "absl/strings/str_cat.h"

namespace imca::env {
namespace {

constexpr int kDRow[kNumMoveActions] = {-1, 1, 0, 0, 0};
constexpr int kDCol[kNumMoveActions] = {0, 0, -1, 1, 0};

// coop_nav (paper 5.1): the agents collect every treasure of the map; an
// agent collects a treasure by stepping on it. Each step costs every agent
// 0.1; collecting the last treasure gives every agent +50 and ends the episode.
class CoopNav final : public Scenario {
 public:
  static constexpr float kStepPenalty = -0.1f;
  static constexpr float kSuccessReward = 50.0f;

  CoopNav(GridMap map, int num_agents, int step_limit)
      : Scenario(std::move(map), num_agents, kNumMoveActions, step_limit),
        all_collected_((1u << map_.treasures().size()) - 1) {}

  absl::string_view name() const override { return "coop_nav"; }
  int num_object_bits() const override { return static_cast<int>(map_.treasures().size()); }

  void Reset(Rng& rng, int32_t* state) const override {
    state[kObjectsIndex] = 0;
    SpawnAgents(state + 1, rng);
    state[1 + num_agents_] = 0;
  }

  StepOutcome Step(int32_t* state, const int32_t* actions, Rng& rng,
                   float* rewards) const override {
    int32_t* cells = state + 1;
    MoveAgents(cells, actions, rng);
    const int t = ++state[1 + num_agents_];
    uint32_t z = static_cast<uint32_t>(state[kObjectsIndex]);
    const auto& treasures = map_.treasures();
    for (int a = 0; a < num_agents_; ++a) {
      for (size_t k = 0; k < treasures.size(); ++k) {
        if (cells[a] == treasures[k]) z |= 1u << k;
      }
    }
    state[kObjectsIndex] = static_cast<int32_t>(z);
    StepOutcome outcome;
    outcome.success = z == all_collected_;
    outcome.terminated = outcome.success;
    outcome.truncated = !outcome.terminated && t >= step_limit_;
    const float reward = kStepPenalty + (outcome.success ? kSuccessReward : 0.0f);
    for (int a = 0; a < num_agents_; ++a) rewards[a] = reward;
    return outcome;
  }

 private:
  uint32_t all_collected_;
};

}  // namespace

void Scenario::MoveAgents(int32_t* cells, const int32_t* actions, Rng& rng) const {
  const int n = num_agents_;
  const int width = map_.width();
  int32_t target[kMaxAgents];
  bool contested = false;
  for (int a = 0; a < n; ++a) {
    const int u = actions[a];
    const int row = map_.Row(cells[a]) + kDRow[u];
    const int col = map_.Col(cells[a]) + kDCol[u];
    target[a] = cells[a];
    if (row < 0 || row >= map_.height() || col < 0 || col >= width) continue;
    const int cell = row * width + col;
    if (!map_.IsWall(cell)) target[a] = cell;
  }
  for (int a = 0; a < n && !contested; ++a) {
    for (int b = a + 1; b < n; ++b) {
      if (target[a] == target[b] && target[a] != cells[a] && target[b] != cells[b]) contested = true;
    }
  }
  // rank[a] < rank[b]: a wins a contested cell. Drawn only when needed, so
  // uncontested steps consume no randomness.
  int rank[kMaxAgents];
  for (int a = 0; a < n; ++a) rank[a] = a;
  if (contested) {
    for (int a = n - 1; a > 0; --a) std::swap(rank[a], rank[rng.Uniform(a + 1)]);
  }
  bool changed = true;
  while (changed) {
    changed = false;
    for (int a = 0; a < n; ++a) {
      if (target[a] == cells[a]) continue;
      for (int b = 0; b < n; ++b) {
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
  for (int a = 0; a < n; ++a) cells[a] = target[a];
}

void Scenario::SpawnAgents(int32_t* cells, Rng& rng) const {
  const auto& pool = map_.random_spawns();
  int32_t taken[kMaxAgents];
  int num_taken = 0;
  for (int a = 0; a < num_agents_; ++a) {
    const int fixed = map_.FixedSpawn(a);
    if (fixed >= 0) {
      cells[a] = fixed;
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
  for (int a = 0; a < num_agents_; ++a) {
    const int32_t cell = state[1 + a];
    if (cell < 0 || cell >= map_.num_cells() || map_.IsWall(cell)) {
      return absl::InvalidArgumentError(absl::StrCat("cell of agent ", a, " is ", cell,
                                                     ", not a floor cell of the map"));
    }
  }
  const int32_t t = state[1 + num_agents_];
  if (t < 0 || t > step_limit_) {
    return absl::InvalidArgumentError(absl::StrCat("step count ", t, " outside [0, ", step_limit_, "]"));
  }
  return absl::OkStatus();
}

std::string Scenario::Render(const int32_t* state) const {
  std::string out;
  const uint32_t z = static_cast<uint32_t>(state[kObjectsIndex]);
  for (int row = 0; row < map_.height(); ++row) {
    for (int col = 0; col < map_.width(); ++col) {
      const int cell = row * map_.width() + col;
      char c = map_.IsWall(cell) ? '#' : '.';
      const auto& treasures = map_.treasures();
      for (size_t k = 0; k < treasures.size(); ++k) {
        if (treasures[k] == cell && !(z >> k & 1u)) c = 'T';
      }
      for (int a = 0; a < num_agents_; ++a) {
        if (state[1 + a] == cell) c = static_cast<char>('1' + a);
      }
      out.push_back(c);
    }
    out.push_back('\n');
  }
  absl::StrAppend(&out, "t=", state[1 + num_agents_], " objects=", z, "\n");
  return out;
}

absl::StatusOr<std::unique_ptr<Scenario>> MakeScenario(const ScenarioConfig& config,
                                                       const std::string& map_dir) {
  if (config.name != "coop_nav") {
    return absl::InvalidArgumentError(
        absl::StrCat("unknown scenario '", config.name, "' (available: coop_nav)"));
  }
  const std::string path =
      config.map_path.empty() ? absl::StrCat(map_dir, "/", config.name, ".txt") : config.map_path;
  absl::StatusOr<GridMap> map = GridMap::Load(path);
  if (!map.ok()) return map.status();
  return MakeScenarioWithMap(config, *std::move(map));
}

absl::StatusOr<std::unique_ptr<Scenario>> MakeScenarioWithMap(const ScenarioConfig& config,
                                                              GridMap map) {
  if (config.name != "coop_nav") {
    return absl::InvalidArgumentError(
        absl::StrCat("unknown scenario '", config.name, "' (available: coop_nav)"));
  }
  const int num_agents = config.num_agents > 0 ? config.num_agents : 2;
  if (num_agents > kMaxAgents) {
    return absl::InvalidArgumentError(absl::StrCat("num_agents ", num_agents, " above ", kMaxAgents));
  }
  int random_needed = 0;
  for (int a = 0; a < num_agents; ++a) random_needed += map.FixedSpawn(a) < 0;
  if (random_needed > static_cast<int>(map.random_spawns().size())) {
    return absl::InvalidArgumentError(absl::StrCat(
        map.source(), ": ", random_needed, " agents need a random spawn but the map has ",
        map.random_spawns().size(), " 'S' cells"));
  }
  if (map.treasures().empty()) {
    return absl::InvalidArgumentError(absl::StrCat(map.source(), ": coop_nav needs at least one 'T'"));
  }
  const int step_limit = config.step_limit > 0 ? config.step_limit : 100;
  if (step_limit > 100000) {
    return absl::InvalidArgumentError(absl::StrCat("step_limit ", step_limit, " above 100000"));
  }
  return std::make_unique<CoopNav>(std::move(map), num_agents, step_limit);
}

std::string DefaultMapDir() {
  if (const char* dir = std::getenv("IMCA_MAP_DIR")) return dir;
  return IMCA_SOURCE_DIR "/maps";
}

}  // namespace imca::env
