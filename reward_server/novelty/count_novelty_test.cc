// Every credit formula of docs/credit.md for count novelty, against numbers
// worked by hand for 2 agents and 5 actions (docs/credit.md shows the work).
#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>

#include "common/env/env.h"
#include "gtest/gtest.h"
#include "reward_server/novelty/count_novelty.h"
#include "reward_server/scorer_testing.h"

namespace imca::reward {
namespace {

using ::imca::testing::CountScorer;

constexpr int kN = 2;
constexpr int kA = 5;
constexpr float kTol = 1e-5f;

class CountScorerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    scenario_ = ::imca::testing::TextScenario();
    ASSERT_NE(scenario_, nullptr);
  }

  using Result = ::imca::testing::ScoredBatch;

  // Scores transitions given as (cells, actions, probs) with z = t = 0.
  Result Score(CountScorer& scorer, const std::vector<std::vector<int32_t>>& cells,
               const std::vector<std::vector<int32_t>>& actions,
               const std::vector<std::vector<float>>& probs, bool dry_run = false) {
    return ::imca::testing::ScoreSteps(scorer, {cells, actions, probs, {}, {}}, dry_run);
  }

  static std::vector<float> Uniform() { return std::vector<float>(2 * kA, 0.2f); }

  std::unique_ptr<env::Scenario> scenario_;
};

ScorerConfig Config(std::string credit, Permutation permutation = Permutation::kOff, double beta = 1.0) {
  ScorerConfig config;
  config.credit = credit;
  config.permutation = permutation;
  config.beta = beta;
  return config;
}

TEST_F(CountScorerTest, FirstVisitSplitsEvenly) {
  CountScorer scorer(*scenario_, Config("imca", Permutation::kOff, 2.0));
  Result r = Score(scorer, {{0, 4}}, {{2, 0}}, {Uniform()});
  EXPECT_NEAR(r.global[0], 2.0f, kTol);  // beta / sqrt(0 + 1).
  EXPECT_NEAR(r.contributions[0], 0.0f, kTol);
  EXPECT_NEAR(r.shares[0], 0.5f, kTol);
  EXPECT_NEAR(r.agent_rewards[0], 1.0f, kTol);
  EXPECT_NEAR(r.agent_rewards[1], 1.0f, kTol);
}

TEST_F(CountScorerTest, CreditGoesToTheAgentWhoseActionWasNovel) {
  CountScorer scorer(*scenario_, Config("imca"));
  for (int i = 0; i < 3; ++i) Score(scorer, {{0, 4}}, {{2, 0}}, {Uniform()});
  std::vector<float> probs = Uniform();
  probs[kA + 0] = 0.5f;  // pi^2(0) = 0.5, others 0.125.
  for (int u = 1; u < kA; ++u) probs[kA + u] = 0.125f;
  Result r = Score(scorer, {{0, 4}}, {{2, 1}}, {probs});
  // N(S,U) = 1; agent 1's counterfactuals (u', 1) are all unseen -> r^1 = 0.
  // Agent 2's: (2, 0) seen 3 times -> 1/2; r^2 = 1 - (0.5 * 0.5 + 0.5 * 1) = 0.25.
  EXPECT_NEAR(r.global[0], 1.0f, kTol);
  EXPECT_NEAR(r.contributions[0], 0.0f, kTol);
  EXPECT_NEAR(r.contributions[1], 0.25f, kTol);
  EXPECT_NEAR(r.shares[1], 0.5621765f, kTol);  // e^.25 / (1 + e^.25).
  EXPECT_NEAR(r.agent_rewards[0], 0.4378235f, kTol);
  EXPECT_NEAR(r.agent_rewards[1], 0.5621765f, kTol);
}

TEST_F(CountScorerTest, CounterfactualOverAllFiveActions) {
  CountScorer scorer(*scenario_, Config("imca"));
  // Counts of (u', 0) for u' = 0..4 become 1, 2, 3, 4, 0.
  for (int u = 0; u < 4; ++u) {
    for (int i = 0; i <= u; ++i) Score(scorer, {{0, 4}}, {{u, 0}}, {Uniform()});
  }
  std::vector<float> probs = {0.1f, 0.2f, 0.3f, 0.25f, 0.15f, 0.2f, 0.2f, 0.2f, 0.2f, 0.2f};
  Result r = Score(scorer, {{0, 4}}, {{4, 0}}, {probs});
  // r^1 = 1 - (.1/sqrt2 + .2/sqrt3 + .3/sqrt4 + .25/sqrt5 + .15/1) = 0.4020159.
  EXPECT_NEAR(r.contributions[0], 0.4020159f, kTol);
  EXPECT_NEAR(r.contributions[1], 0.0f, kTol);
  EXPECT_NEAR(r.shares[0], 0.5991719f, kTol);
  EXPECT_NEAR(r.agent_rewards[0], 0.5991719f, kTol);
  EXPECT_NEAR(r.agent_rewards[1], 0.4008281f, kTol);
  EXPECT_EQ(scorer.JointCount(std::vector<int32_t>{0, 0, 4, 0}.data(), std::vector<int32_t>{4, 0}.data()), 1u);
}

TEST_F(CountScorerTest, TemperatureSharpensShares) {
  ScorerConfig config = Config("imca");
  config.temperature = 0.1;
  CountScorer scorer(*scenario_, config);
  for (int i = 0; i < 3; ++i) Score(scorer, {{0, 4}}, {{2, 0}}, {Uniform()});
  Result r = Score(scorer, {{0, 4}}, {{2, 1}}, {Uniform()});
  // r^1 = 0, r^2 = 1 - (0.2 * 0.5 + 0.8) = 0.1; p^2 = 1 / (1 + e^-1).
  EXPECT_NEAR(r.contributions[1], 0.1f, kTol);
  EXPECT_NEAR(r.shares[1], 0.7310586f, kTol);
}

TEST_F(CountScorerTest, BatchEqualsOneByOneInOrder) {
  CountScorer batched(*scenario_, Config("shared"));
  CountScorer single(*scenario_, Config("shared"));
  Result r = Score(batched, {{0, 4}, {0, 4}, {1, 4}, {0, 4}}, {{2, 0}, {2, 0}, {2, 0}, {2, 0}},
                   {Uniform(), Uniform(), Uniform(), Uniform()});
  const float expected[] = {1.0f, 1.0f / std::sqrt(2.0f), 1.0f, 1.0f / std::sqrt(3.0f)};
  for (int i = 0; i < 4; ++i) {
    EXPECT_NEAR(r.global[i], expected[i], kTol) << i;
    EXPECT_EQ(r.agent_rewards[2 * i], r.global[i]);  // Shared: everyone gets R_i.
    EXPECT_EQ(r.agent_rewards[2 * i + 1], r.global[i]);
  }
  const std::vector<std::vector<int32_t>> cells = {{0, 4}, {0, 4}, {1, 4}, {0, 4}};
  for (int i = 0; i < 4; ++i) {
    Result one = Score(single, {cells[i]}, {{2, 0}}, {Uniform()});
    EXPECT_EQ(one.global[0], r.global[i]);
  }
}

TEST_F(CountScorerTest, DryRunChangesNothing) {
  CountScorer scorer(*scenario_, Config("imca"));
  Score(scorer, {{0, 4}}, {{2, 0}}, {Uniform()}, /*dry_run=*/true);
  Result r = Score(scorer, {{0, 4}}, {{2, 0}}, {Uniform()});
  EXPECT_NEAR(r.global[0], 1.0f, kTol);
}

TEST_F(CountScorerTest, NoneGivesZerosAndTouchesNoTable) {
  CountScorer scorer(*scenario_, Config("none"));
  Result r = Score(scorer, {{0, 4}}, {{2, 0}}, {Uniform()});
  EXPECT_EQ(r.global[0], 0.0f);
  EXPECT_EQ(r.agent_rewards[0], 0.0f);
  EXPECT_EQ(r.agent_rewards[1], 0.0f);
  v1::RewardStats stats;
  scorer.FillStats(&stats);
  EXPECT_EQ(stats.distinct_keys(), 0);
  EXPECT_EQ(stats.distinct_local_keys(), 0);
}

TEST_F(CountScorerTest, IndependentUsesEachAgentsLocalCounts) {
  CountScorer scorer(*scenario_, Config("independent", Permutation::kOff, 3.0));
  Score(scorer, {{0, 4}}, {{2, 0}}, {Uniform()});
  // Agent 1 repeats (cell 0, action 2); agent 2 does something new.
  Result r = Score(scorer, {{0, 3}}, {{2, 0}}, {Uniform()});
  EXPECT_NEAR(r.agent_rewards[0], 3.0f / std::sqrt(2.0f), kTol);
  EXPECT_NEAR(r.agent_rewards[1], 3.0f, kTol);
  EXPECT_NEAR(r.global[0], 3.0f / std::sqrt(2.0f) + 3.0f, kTol);
  EXPECT_NEAR(r.shares[0], (1 / std::sqrt(2.0f)) / (1 / std::sqrt(2.0f) + 1), kTol);
}

TEST_F(CountScorerTest, IndependentWithPermutationSharesOneLocalTable) {
  CountScorer off(*scenario_, Config("independent", Permutation::kOff));
  CountScorer canonical(*scenario_, Config("independent", Permutation::kCanonical));
  for (CountScorer* s : {&off, &canonical}) Score(*s, {{0, 4}}, {{2, 0}}, {Uniform()});
  // Now agent 2 stands where agent 1 stood and does what it did.
  Result r_off = Score(off, {{1, 0}}, {{3, 2}}, {Uniform()});
  Result r_canonical = Score(canonical, {{1, 0}}, {{3, 2}}, {Uniform()});
  EXPECT_NEAR(r_off.agent_rewards[1], 1.0f, kTol);
  EXPECT_NEAR(r_canonical.agent_rewards[1], 1.0f / std::sqrt(2.0f), kTol);
}

TEST_F(CountScorerTest, CanonicalPermutationMakesSwappedAgentsOneKey) {
  CountScorer off(*scenario_, Config("imca", Permutation::kOff));
  CountScorer canonical(*scenario_, Config("imca", Permutation::kCanonical));
  std::vector<float> probs = Uniform();
  probs[0] = 0.1f;
  probs[1] = 0.3f;  // pi^1(1) = 0.3 (the action agent 1 takes below).
  probs[2] = 0.2f;
  probs[3] = 0.2f;
  probs[4] = 0.2f;
  for (CountScorer* s : {&off, &canonical}) Score(*s, {{0, 4}}, {{2, 1}}, {Uniform()});
  // Swapped: agent 1 at cell 4 doing 1, agent 2 at cell 0 doing 2.
  Result r_off = Score(off, {{4, 0}}, {{1, 2}}, {probs});
  Result r_canonical = Score(canonical, {{4, 0}}, {{1, 2}}, {probs});
  EXPECT_NEAR(r_off.global[0], 1.0f, kTol);
  EXPECT_NEAR(r_canonical.global[0], 1.0f / std::sqrt(2.0f), kTol);
  // Canonical counterfactual of agent 1: only u' = 1 hits the seen key:
  // r^1 = 1/sqrt2 - (0.3/sqrt2 + 0.7) = -0.2050253.
  EXPECT_NEAR(r_canonical.contributions[0], -0.2050253f, kTol);
  // Agent 2 (uniform pi): r^2 = 1/sqrt2 - (0.2/sqrt2 + 0.8) = -0.2343146.
  EXPECT_NEAR(r_canonical.contributions[1], -0.2343146f, kTol);
}

TEST_F(CountScorerTest, RandomPermutationIncrementsAPermutedKey) {
  int identity = 0, swapped = 0;
  const std::vector<int32_t> state = {0, 0, 4, 0}, swapped_state = {0, 4, 0, 0};
  const std::vector<int32_t> actions = {2, 1}, swapped_actions = {1, 2};
  for (uint64_t seed = 1; seed <= 64; ++seed) {
    ScorerConfig config = Config("shared", Permutation::kRandom);
    config.seed = seed;
    CountScorer scorer(*scenario_, config);
    Score(scorer, {{0, 4}}, {{2, 1}}, {Uniform()});
    const uint32_t a = scorer.JointCount(state.data(), actions.data());
    const uint32_t b = scorer.JointCount(swapped_state.data(), swapped_actions.data());
    ASSERT_EQ(a + b, 1u);
    identity += a;
    swapped += b;
  }
  EXPECT_GT(identity, 10);
  EXPECT_GT(swapped, 10);
}

TEST_F(CountScorerTest, SnapshotRoundTripGivesIdenticalScores) {
  const std::string path = ::testing::TempDir() + "/count_snapshot.bin";
  CountScorer scorer(*scenario_, Config("imca"));
  for (int i = 0; i < 5; ++i) Score(scorer, {{0, 4}}, {{i % 5, 0}}, {Uniform()});
  ASSERT_TRUE(scorer.Save(path).ok());
  CountScorer restored(*scenario_, Config("imca"));
  ASSERT_TRUE(restored.Load(path).ok());
  Result a = Score(scorer, {{0, 4}}, {{1, 0}}, {Uniform()});
  Result b = Score(restored, {{0, 4}}, {{1, 0}}, {Uniform()});
  EXPECT_EQ(a.agent_rewards, b.agent_rewards);
  CountScorer other(*scenario_, Config("shared"));
  EXPECT_EQ(other.Load(path).code(), absl::StatusCode::kFailedPrecondition);
  std::remove(path.c_str());
}

}  // namespace
}  // namespace imca::reward
