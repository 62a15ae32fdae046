#include "reward_server/novelty/influence_novelty.h"

#include <cmath>

#include "absl/container/flat_hash_map.h"
#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"

namespace imca::reward {
namespace {

constexpr char kMagic[] = "IMCA-INFLUENCE-1";

// What makes the keys below exact: agent ids below 15 (15 marks the own-agent
// tables), cells below 2^16, actions below 2^3 (MakeNovelty checks).
static_assert(env::kMaxAgents < 15);
static_assert(env::GridMap::kMaxSide * env::GridMap::kMaxSide <= 65536);

// Exact keys: tag (2 bits), i and j (4 each), cells (16 each), actions (3 each).
enum Tag : uint64_t { kPairNext = 0, kPair = 1, kOwnNext = 2, kOwn = 3 };

uint64_t PairKey(Tag tag, int i, int j, int32_t s_i, int32_t a_i, int32_t s_j, int32_t a_j, int32_t next_j) {
  uint64_t key = tag;
  key = key << 4 | static_cast<uint64_t>(i);
  key = key << 4 | static_cast<uint64_t>(j);
  key = key << 16 | static_cast<uint64_t>(s_i);
  key = key << 3 | static_cast<uint64_t>(a_i);
  key = key << 16 | static_cast<uint64_t>(s_j);
  key = key << 3 | static_cast<uint64_t>(a_j);
  key = key << 16 | static_cast<uint64_t>(next_j);
  return key;
}

uint64_t OwnKey(Tag tag, int j, int32_t s_j, int32_t a_j, int32_t next_j) {
  return PairKey(tag, 15, j, 0, 0, s_j, a_j, next_j);
}

uint64_t CellKey(int i, int32_t cell) { return static_cast<uint64_t>(i) << 16 | static_cast<uint64_t>(cell); }

// Adds one transition (the agents' cells, actions and reached cells) to
// `pending`: each agent's own tables and those of every ordered pair.
void AddTransition(int n, const int32_t* cells, const int32_t* actions, const int32_t* reached,
                   absl::flat_hash_map<uint64_t, uint32_t>* pending) {
  for (int j = 0; j < n; ++j) {
    ++(*pending)[OwnKey(kOwnNext, j, cells[j], actions[j], reached[j])];
    ++(*pending)[OwnKey(kOwn, j, cells[j], actions[j], 0)];
    for (int i = 0; i < n; ++i) {
      if (i == j) continue;
      ++(*pending)[PairKey(kPairNext, i, j, cells[i], actions[i], cells[j], actions[j], reached[j])];
      ++(*pending)[PairKey(kPair, i, j, cells[i], actions[i], cells[j], actions[j], 0)];
    }
  }
}

}  // namespace

InfluenceNovelty::InfluenceNovelty(const env::Scenario& scenario, const ScorerConfig& config,
                                   const InfluenceConfig& influence)
    : CountedNovelty(2, config.deterministic),
      scenario_tag_(absl::StrCat(scenario.name(), " ", scenario.map().width(), "x", scenario.map().height())),
      n_(scenario.num_agents()),
      k_(scenario.state_size()),
      step_index_(scenario.step_index()),
      influence_(influence) {}

float InfluenceNovelty::Influence(const int32_t* state, const int32_t* actions, const int32_t* next, int i, int j,
                                  const absl::flat_hash_map<uint64_t, uint32_t>& pending) const {
  auto count = [&](uint64_t key) {
    auto it = pending.find(key);
    return static_cast<double>(store_.Get(kTransitions, key)) + (it == pending.end() ? 0.0 : it->second);
  };
  const int32_t* cells = state + 1;
  const int32_t* reached = next + 1;
  const double own = count(OwnKey(kOwnNext, j, cells[j], actions[j], reached[j])) /
                     count(OwnKey(kOwn, j, cells[j], actions[j], 0));
  const double pair = count(PairKey(kPairNext, i, j, cells[i], actions[i], cells[j], actions[j], reached[j])) /
                      count(PairKey(kPair, i, j, cells[i], actions[i], cells[j], actions[j], 0));
  // Both counts include this transition, so neither ratio is 0 or undefined.
  return static_cast<float>(influence_.log_form ? std::log(pair) - std::log(own) : 1.0 - own / pair);
}

absl::Status InfluenceNovelty::Compute(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out) {
  const int n = n_;
  const int64_t E = batch.num_envs, K = k_;
  if (out.local == nullptr) {
    return absl::InternalError("eiti/edti: only independent credit (a local novelty) is served");
  }
  absl::flat_hash_map<uint64_t, uint32_t> pending;
  for (int64_t t = 0; t < batch.length; ++t) {
    // 1. Add every env's transition of this step (not those out of a reset state).
    pending.clear();
    for (int64_t e = 0; e < E; ++e) {
      const int64_t row = t * E + e;
      const int32_t* state = batch.states + row * K;
      if (state[step_index_] == 0) continue;
      AddTransition(n, state + 1, batch.actions + row * n, batch.next_states + row * K + 1, &pending);
    }
    // 2. Read the influences and the curiosity (its counts before this step).
    for (int64_t e = 0; e < E; ++e) {
      const int64_t row = t * E + e;
      const int32_t* state = batch.states + row * K;
      const int32_t* next = batch.next_states + row * K;
      const int32_t* actions = batch.actions + row * n;
      const bool counted = state[step_index_] != 0;
      for (int i = 0; i < n; ++i) {
        double sum = 0;
        for (int j = 0; j < n; ++j) {
          const float c = counted && i != j ? Influence(state, actions, next, i, j, pending) : 0.0f;
          if (out.influences != nullptr) out.influences[(row * n + i) * n + j] = c;
          sum += c;
        }
        const double curiosity =
            influence_.eta / std::sqrt(static_cast<double>(store_.Get(kCells, CellKey(i, next[1 + i]))) + 1.0);
        out.local[row * n + i] = static_cast<float>(curiosity + (influence_.edti ? 0.0 : influence_.beta_t * sum));
      }
    }
    if (dry_run) continue;
    for (const auto& [key, count] : pending) store_.Add(kTransitions, key, count);
    for (int64_t e = 0; e < E; ++e) {
      const int32_t* next = batch.next_states + (t * E + e) * K;
      for (int i = 0; i < n; ++i) store_.Increment(kCells, CellKey(i, next[1 + i]));
    }
  }
  // Journaled before the response goes out.
  return store_.Commit(dry_run ? 0 : batch.size);
}

void InfluenceNovelty::FillStats(v1::RewardStats* stats) const {
  stats->set_distinct_keys(store_.table(kTransitions).size());
  stats->set_distinct_local_keys(store_.table(kCells).size());
}

std::string InfluenceNovelty::ConfigTag() const {
  return absl::StrCat(kMagic, " ", scenario_tag_, " n=", n_, " kind=", influence_.edti ? "edti" : "eiti",
                      " log=", influence_.log_form);
}

}  // namespace imca::reward
