// RND novelty with credit assignment (paper eq. 6, 9-10), on tiny networks
// whose weights the test sets, and the learned-model properties.
#include "reward_server/make_scorer.h"
#include "reward_server/novelty/rnd_novelty.h"

#include "reward_server/scorer_testing.h"

#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>

#include "common/env/env.h"
#include "common/nn/threads.h"
#include "common/protocol/test_unrolls.h"
#include "gtest/gtest.h"

namespace imca::reward {
namespace {

using ::imca::testing::Credited;

constexpr int kN = 2;
constexpr int kA = 5;

using Scored = ::imca::testing::ScoredBatch;

class RndScorerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    nn::SetTorchThreads(1);  // As the reward server sets it (--threads).
    scenario_ = ::imca::testing::TextScenario();
    ASSERT_NE(scenario_, nullptr);
  }

  Scored Score(Scorer& scorer, const std::vector<std::vector<int32_t>>& cells,
               const std::vector<std::vector<int32_t>>& actions, const std::vector<std::vector<float>>& probs,
               bool dry_run) {
    return ::imca::testing::ScoreSteps(scorer, {cells, actions, probs, {}, {}}, dry_run);
  }

  Scored ScoreUnroll(Scorer& scorer, const v1::Unroll& u, bool dry_run) {
    return ::imca::testing::ScoreUnroll(scorer, u, dry_run);
  }

  std::unique_ptr<Credited<RndNovelty>> Make(std::string credit, Permutation permutation, RndConfig rnd = {}) {
    ScorerConfig config;
    config.credit = credit;
    config.permutation = permutation;
    auto kind = RndNovelty::Create(*scenario_, config, rnd);
    EXPECT_TRUE(kind.ok()) << kind.status();
    return std::make_unique<Credited<RndNovelty>>(*std::move(kind), config, scenario_->num_agents());
  }

  std::unique_ptr<env::Scenario> scenario_;
};

TEST_F(RndScorerTest, CounterfactualCreditMatchesHandWorkedNumbers) {
  // One linear layer, no normalisation: N(x) = (w . x)^2 with a zero predictor.
  RndConfig rnd;
  rnd.hidden = {};
  rnd.output = 1;
  rnd.normalize = false;
  auto scorer = Make("imca", Permutation::kOff, rnd);
  // Input: 13 state floats (2 agents x (1 + 5) one-hots + 1 treasure bit), then
  // 5 action one-hots for agent 1 and 5 for agent 2. Target weights: 0.5 u for
  // agent 1's action u, 1 for agent 2's action 0.
  std::vector<float> w(23, 0.0f);
  for (int u = 0; u < kA; ++u) w[13 + u] = 0.5f * u;
  w[18] = 1.0f;
  ASSERT_TRUE(scorer->kind().SetLinearForTest("target", 0, w, {0.0f}).ok());
  ASSERT_TRUE(scorer->kind().SetLinearForTest("predictor", 0, std::vector<float>(23, 0.0f), {0.0f}).ok());
  const std::vector<float> uniform(2 * kA, 0.2f);
  Scored r = Score(*scorer, {{0, 4}}, {{2, 0}}, {uniform}, /*dry_run=*/true);
  // N(S,U) = (1 + 1)^2 = 4.
  EXPECT_NEAR(r.global[0], 4.0f, 1e-5);
  // Agent 1: (0.5u' + 1)^2 = 1, 2.25, 4, 6.25, 9 -> mean 4.5 -> r^1 = -0.5.
  EXPECT_NEAR(r.contributions[0], -0.5f, 1e-5);
  // Agent 2: (1 + [u'=0])^2 = 4, 1, 1, 1, 1 -> mean 1.6 -> r^2 = 2.4.
  EXPECT_NEAR(r.contributions[1], 2.4f, 1e-5);
  // p^2 = 1 / (1 + e^-2.9).
  EXPECT_NEAR(r.shares[1], 0.9478464f, 1e-5);
  EXPECT_NEAR(r.agent_rewards[0], 0.2086145f, 1e-5);
  EXPECT_NEAR(r.agent_rewards[1], 3.7913855f, 1e-5);
  ASSERT_FALSE(scorer->kind().SetLinearForTest("target", 0, {1.0f}, {0.0f}).ok());
}

TEST_F(RndScorerTest, CounterfactualsOfADeepNormalisedModelEqualScoringTheAlternatives) {
  // The scorer computes counterfactual rows from the taken row's first layer;
  // scoring each alternative joint action as a transition of its own must give
  // the same novelties (eq. 9), for either slot order.
  for (Permutation permutation : {Permutation::kOff, Permutation::kCanonical}) {
    auto scorer = Make("imca", permutation);
    for (int i = 0; i < 20; ++i) ScoreUnroll(*scorer, testing::RandomUnroll(*scenario_, 8, 4, 11 + i), false);
    const std::vector<float> probs = {0.1f, 0.2f, 0.3f, 0.2f, 0.2f, 0.4f, 0.1f, 0.1f, 0.2f, 0.2f};
    const std::vector<int32_t> taken = {2, 1};
    // Agent 2 stands left of agent 1: the canonical order swaps their slots.
    const std::vector<int32_t> cells = {4, 0};
    const Scored r = Score(*scorer, {cells}, {taken}, {probs}, true);
    ASSERT_GT(r.global[0], 0.0f);
    for (int a = 0; a < kN; ++a) {
      double baseline = 0;
      for (int u = 0; u < kA; ++u) {
        std::vector<int32_t> actions = taken;
        actions[a] = u;
        baseline += probs[a * kA + u] * Score(*scorer, {cells}, {actions}, {probs}, true).global[0];
      }
      EXPECT_NEAR(r.contributions[a], r.global[0] - baseline, 1e-4 * r.global[0])
          << "agent " << a << " permutation " << PermutationName(permutation);
    }
  }
}

TEST_F(RndScorerTest, BonusOfARepeatedlyScoredStateFalls) {
  RndConfig rnd;
  rnd.normalize = false;
  auto scorer = Make("shared", Permutation::kOff, rnd);
  const v1::Unroll u = testing::RandomUnroll(*scenario_, 8, 4, 3);
  auto mean = [](const Scored& s) {
    double sum = 0;
    for (float x : s.global) sum += x;
    return sum / s.global.size();
  };
  const double first = mean(ScoreUnroll(*scorer, u, /*dry_run=*/true));
  for (int i = 0; i < 100; ++i) ScoreUnroll(*scorer, u, /*dry_run=*/false);
  const double last = mean(ScoreUnroll(*scorer, u, /*dry_run=*/true));
  EXPECT_GT(first, 0.0);
  EXPECT_LT(last, 0.2 * first);
  // A dry run leaves the model alone.
  EXPECT_EQ(mean(ScoreUnroll(*scorer, u, true)), last);
}

TEST_F(RndScorerTest, CanonicalPermutationGivesPermutedAgentsIdenticalBonuses) {
  auto canonical = Make("imca", Permutation::kCanonical);
  auto off = Make("imca", Permutation::kOff);
  std::vector<float> probs = {0.1f, 0.2f, 0.3f, 0.2f, 0.2f, 0.4f, 0.1f, 0.1f, 0.2f, 0.2f};
  std::vector<float> swapped(probs.begin() + kA, probs.end());
  swapped.insert(swapped.end(), probs.begin(), probs.begin() + kA);
  const Scored a = Score(*canonical, {{0, 4}}, {{2, 1}}, {probs}, true);
  const Scored b = Score(*canonical, {{4, 0}}, {{1, 2}}, {swapped}, true);
  EXPECT_EQ(a.global[0], b.global[0]);
  EXPECT_EQ(a.contributions[0], b.contributions[1]);
  EXPECT_EQ(a.agent_rewards[0], b.agent_rewards[1]);
  EXPECT_EQ(a.agent_rewards[1], b.agent_rewards[0]);
  const Scored c = Score(*off, {{0, 4}}, {{2, 1}}, {probs}, true);
  const Scored d = Score(*off, {{4, 0}}, {{1, 2}}, {swapped}, true);
  EXPECT_NE(c.global[0], d.global[0]);
}

TEST_F(RndScorerTest, IndependentCreditScoresEachAgentLocally) {
  auto scorer = Make("independent", Permutation::kOff);
  const v1::Unroll u = testing::RandomUnroll(*scenario_, 8, 4, 5);
  const Scored r = ScoreUnroll(*scorer, u, false);
  for (size_t i = 0; i < r.global.size(); ++i) {
    EXPECT_GT(r.agent_rewards[2 * i], 0.0f);
    EXPECT_NEAR(r.agent_rewards[2 * i] + r.agent_rewards[2 * i + 1], r.global[i], 1e-4);
  }
}

TEST_F(RndScorerTest, SnapshotRoundTripGivesIdenticalOutputs) {
  const std::string path = ::testing::TempDir() + "/rnd_snapshot_" + std::to_string(getpid()) + ".pt";
  auto scorer = Make("imca", Permutation::kOff);
  const v1::Unroll u = testing::RandomUnroll(*scenario_, 8, 4, 7);
  for (int i = 0; i < 5; ++i) ScoreUnroll(*scorer, u, false);
  ASSERT_TRUE(scorer->Save(path).ok());
  ScorerConfig config;
  config.credit = "imca";
  config.seed = 99;  // Other initial weights: everything must come from the file.
  auto made = MakeScorer("rnd", *scenario_, config);
  ASSERT_TRUE(made.ok());
  std::unique_ptr<CreditScorer> restored = *std::move(made);
  ASSERT_TRUE(restored->Load(path).ok());
  const Scored a = ScoreUnroll(*scorer, u, false);
  const Scored b = ScoreUnroll(*restored, u, false);
  EXPECT_EQ(a.agent_rewards, b.agent_rewards);
  // And they keep learning identically.
  EXPECT_EQ(ScoreUnroll(*scorer, u, true).global, ScoreUnroll(*restored, u, true).global);
  auto other = Make("shared", Permutation::kOff);
  EXPECT_EQ(other->Load(path).code(), absl::StatusCode::kFailedPrecondition);
  std::remove(path.c_str());
}

}  // namespace
}  // namespace imca::reward
