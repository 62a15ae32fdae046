#ifndef IMCA_REWARD_SERVER_SCORER_TESTING_H_
#define IMCA_REWARD_SERVER_SCORER_TESTING_H_

// Test helpers: run a Scorer on hand-written transitions or on an Unroll.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/env/env.h"
#include "gtest/gtest.h"
#include "imca/v1/unroll.pb.h"
#include "reward_server/credit_scorer.h"
#include "reward_server/novelty/count_novelty.h"
#include "reward_server/novelty/novelty.h"
#include "reward_server/scorer.h"

namespace imca::testing {

using reward::Scorer;
using reward::TransitionBatch;

// A Scorer that forwards every call to `real` (not owned); tests override
// Score to inject a fault or hold a call.
class ForwardingScorer : public reward::Scorer {
 public:
  explicit ForwardingScorer(reward::Scorer* real) : real_(real) {}
  absl::Status Score(const reward::TransitionBatch& batch, bool dry_run, const reward::ScoreOutput& out) override {
    return real_->Score(batch, dry_run, out);
  }
  bool ReturnsInfluences() const override { return real_->ReturnsInfluences(); }
  void FillStats(v1::RewardStats* stats) const override { real_->FillStats(stats); }
  absl::Status Save(const std::string& path) const override { return real_->Save(path); }
  absl::Status Load(const std::string& path) override { return real_->Load(path); }
  absl::Status Restore(const std::string& path, bool sync) override { return real_->Restore(path, sync); }
  std::optional<int64_t> DurableTransitions() const override { return real_->DurableTransitions(); }

 private:
  reward::Scorer* real_;
};

// coop_nav's rules on a map given as text (default: a 5-cell line, agent 1
// on cell 0, agent 2 on cell 4): the small scenario the scorer tests share.
inline std::unique_ptr<env::Scenario> TextScenario(const char* map_text = "1..T2\n") {
  auto map = env::GridMap::Parse(map_text, "line");
  EXPECT_TRUE(map.ok()) << map.status();
  auto scenario = env::MakeScenarioWithMap(env::ScenarioConfig{}, *std::move(map));
  EXPECT_TRUE(scenario.ok()) << scenario.status();
  return scenario.ok() ? *std::move(scenario) : nullptr;
}

// Reward kind K under the one credit rule, with K's test probes reachable.
template <typename K>
class Credited : public reward::CreditScorer {
 public:
  Credited(std::unique_ptr<K> kind, const reward::ScorerConfig& config, int n)
      : CreditScorer(std::move(kind), config, n) {}
  K& kind() { return static_cast<K&>(novelty()); }
};

// Count novelty with credit, as the reward server builds it.
class CountScorer : public Credited<reward::CountNovelty> {
 public:
  CountScorer(const env::Scenario& scenario, const reward::ScorerConfig& config)
      : Credited(std::make_unique<reward::CountNovelty>(scenario, config), config, scenario.num_agents()) {}
  uint32_t JointCount(const int32_t* state, const int32_t* actions) { return kind().JointCount(state, actions); }
};

struct ScoredBatch {
  std::vector<float> global, contributions, shares, agent_rewards;
};

// Transitions of 2 agents on a map without objects, state [0, cell_1,
// cell_2, 0], scored as one env of T = cells.size() steps, episode 7.
struct TwoAgentSteps {
  std::vector<std::vector<int32_t>> cells;
  std::vector<std::vector<int32_t>> actions;      // Default: stay.
  std::vector<std::vector<float>> probs;          // Default: uniform over 5.
  std::vector<std::vector<int32_t>> next_cells;   // Default: cells.
  std::vector<bool> terminated;                   // Default: none.
};

inline ScoredBatch RunScorer(Scorer& scorer, const TransitionBatch& batch, int n, bool dry_run) {
  ScoredBatch r;
  r.global.resize(batch.size);
  r.contributions.resize(batch.size * n);
  r.shares.resize(batch.size * n);
  r.agent_rewards.resize(batch.size * n);
  EXPECT_TRUE(
      scorer.Score(batch, dry_run, {r.global.data(), r.contributions.data(), r.shares.data(), r.agent_rewards.data()})
          .ok());
  return r;
}

inline ScoredBatch ScoreSteps(Scorer& scorer, const TwoAgentSteps& steps, bool dry_run) {
  const int64_t size = steps.cells.size();
  std::vector<int32_t> states, next_states, actions;
  std::vector<float> probs;
  std::vector<int64_t> episode_ids(size, 7);
  std::unique_ptr<bool[]> terminated(new bool[size]);
  for (int64_t i = 0; i < size; ++i) {
    const auto& next = steps.next_cells.empty() ? steps.cells[i] : steps.next_cells[i];
    states.insert(states.end(), {0, steps.cells[i][0], steps.cells[i][1], 0});
    next_states.insert(next_states.end(), {0, next[0], next[1], 1});
    if (steps.actions.empty()) {
      actions.insert(actions.end(), {4, 4});
    } else {
      actions.insert(actions.end(), steps.actions[i].begin(), steps.actions[i].end());
    }
    if (steps.probs.empty()) {
      probs.insert(probs.end(), 10, 0.2f);
    } else {
      probs.insert(probs.end(), steps.probs[i].begin(), steps.probs[i].end());
    }
    terminated[i] = !steps.terminated.empty() && steps.terminated[i];
  }
  const TransitionBatch batch{size, size, 1, 4, states.data(), next_states.data(), actions.data(), probs.data(),
                              episode_ids.data(), terminated.get(), 42};
  return RunScorer(scorer, batch, 2, dry_run);
}

inline ScoredBatch ScoreUnroll(Scorer& scorer, const v1::Unroll& u, bool dry_run) {
  const TransitionBatch batch{int64_t{u.length()} * u.num_envs(), u.length(), u.num_envs(), u.state_size(),
                              u.states().data(), u.next_states().data(), u.actions().data(),
                              u.action_probs().data(), u.episode_ids().data(), u.terminated().data(), 1};
  return RunScorer(scorer, batch, u.num_agents(), dry_run);
}

}  // namespace imca::testing

#endif  // IMCA_REWARD_SERVER_SCORER_TESTING_H_
