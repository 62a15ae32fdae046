#include "reward_server/novelty/count_novelty.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <optional>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"

namespace imca::reward {
namespace {

constexpr char kMagic[] = "IMCA-COUNT-1";

float CountBonus(uint32_t count_before) {
  return static_cast<float>(1.0 / std::sqrt(static_cast<double>(count_before) + 1.0));
}

}  // namespace

CountNovelty::CountNovelty(const env::Scenario& scenario, const ScorerConfig& config)
    : CountedNovelty(2, config.deterministic),
      scenario_tag_(absl::StrCat(scenario.name(), " ", scenario.map().width(), "x", scenario.map().height())),
      n_(scenario.num_agents()),
      num_actions_(scenario.num_actions()),
      k_(scenario.state_size()),
      config_(config),
      codec_(scenario),
      rng_(config.seed) {}

uint32_t CountNovelty::JointCount(const int32_t* state, const int32_t* actions) const {
  int order[env::kMaxAgents];
  codec_.SlotOrder(state, config_.permutation == Permutation::kCanonical, order);
  return store_.Get(kGlobal, codec_.GlobalKey(state, actions, order));
}

absl::Status CountNovelty::Compute(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out) {
  // Deterministic: the random permutations of a call come from its own
  // stream, not from the order calls arrive in.
  std::optional<Rng> call_rng;
  if (config_.deterministic) call_rng.emplace(NamedSeed(config_.seed, batch.actor_id, batch.sequence));
  Rng& rng = call_rng.has_value() ? *call_rng : rng_;
  for (int64_t i = 0; i < batch.size; ++i) {
    ComputeOne(batch.states + i * k_, batch.actions + i * n_, batch.action_probs + i * n_ * num_actions_, dry_run,
               out, i, rng);
  }
  // Journaled before the response goes out.
  return store_.Commit(dry_run ? 0 : batch.size);
}

void CountNovelty::ComputeOne(const int32_t* state, const int32_t* actions, const float* probs, bool dry_run,
                              const NoveltyOutput& out, int64_t i, Rng& rng) {
  if (out.local != nullptr) {
    const bool shared_table = config_.permutation != Permutation::kOff;
    for (int a = 0; a < n_; ++a) {
      out.local[i * n_ + a] = CountBonus(store_.Get(kLocal, codec_.LocalKey(state, a, actions[a], shared_table)));
    }
    if (!dry_run) {
      for (int a = 0; a < n_; ++a) store_.Increment(kLocal, codec_.LocalKey(state, a, actions[a], shared_table));
    }
    return;
  }
  int order[env::kMaxAgents];
  codec_.SlotOrder(state, config_.permutation == Permutation::kCanonical, order);
  const uint64_t key = codec_.GlobalKey(state, actions, order);
  const float novelty = CountBonus(store_.Get(kGlobal, key));
  out.joint[i] = novelty;
  if (out.contributions != nullptr) {
    // Counterfactuals: agent a's action replaced by every u', all probed
    // against the counts before this transition's increment.
    int32_t counterfactual[env::kMaxAgents];
    for (int a = 0; a < n_; ++a) counterfactual[a] = actions[a];
    for (int a = 0; a < n_; ++a) {
      double baseline = 0;
      for (int u = 0; u < num_actions_; ++u) {
        counterfactual[a] = u;
        // The taken action's pair is (S, U) itself: its novelty was read above.
        const float n_u =
            u == actions[a] ? novelty : CountBonus(store_.Get(kGlobal, codec_.GlobalKey(state, counterfactual, order)));
        baseline += probs[a * num_actions_ + u] * n_u;
      }
      counterfactual[a] = actions[a];
      out.contributions[i * n_ + a] = static_cast<float>(novelty - baseline);
    }
  }
  if (dry_run) return;
  if (config_.permutation == Permutation::kRandom) {
    for (int slot = n_ - 1; slot > 0; --slot) std::swap(order[slot], order[rng.Uniform(slot + 1)]);
    store_.Increment(kGlobal, codec_.GlobalKey(state, actions, order));
  } else {
    store_.Increment(kGlobal, key);
  }
}

void CountNovelty::FillStats(v1::RewardStats* stats) const {
  stats->set_distinct_keys(store_.table(kGlobal).size());
  stats->set_distinct_local_keys(store_.table(kLocal).size());
}

std::string CountNovelty::ConfigTag() const {
  return absl::StrCat(kMagic, " ", scenario_tag_, " n=", n_, " A=", num_actions_,
                      " exact=", codec_.exact(), " credit=", config_.credit,
                      " permutation=", PermutationName(config_.permutation));
}

}  // namespace imca::reward
