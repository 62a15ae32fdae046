// Successor-feature control with credit assignment (paper eq. 7, 11-13).
#include "reward_server/make_scorer.h"
#include "reward_server/novelty/sf_novelty.h"

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

using Scored = ::imca::testing::ScoredBatch;

class SfScorerTest : public ::testing::Test {
 protected:
  void Use(const char* map_text) {
    scenario_ = ::imca::testing::TextScenario(map_text);
    ASSERT_NE(scenario_, nullptr);
  }
  void SetUp() override {
    nn::SetTorchThreads(1);  // As the reward server sets it (--threads).
    Use("1..T2\n");
  }

  // One env, T = transitions; cells are (agent 1, agent 2) before and after.
  Scored Score(Scorer& scorer, const std::vector<std::vector<int32_t>>& now,
               const std::vector<std::vector<int32_t>>& next, const std::vector<bool>& terminated, bool dry_run) {
    return ::imca::testing::ScoreSteps(scorer, {now, {}, {}, next, terminated}, dry_run);
  }

  std::unique_ptr<Credited<SfNovelty>> Make(std::string credit, SfConfig sf = {}) {
    ScorerConfig config;
    config.credit = credit;
    auto kind = SfNovelty::Create(*scenario_, config, sf);
    EXPECT_TRUE(kind.ok()) << kind.status();
    return std::make_unique<Credited<SfNovelty>>(*std::move(kind), config, scenario_->num_agents());
  }

  std::unique_ptr<env::Scenario> scenario_;
};

TEST_F(SfScorerTest, SharesAndEpisodicCountsMatchHandWorkedNumbers) {
  SfConfig sf;
  sf.hidden = {};
  sf.features = 2;
  auto scorer = Make("imca", sf);
  // State input: agent 1 [row(1) | col(5)], agent 2 [row | col], treasure bit.
  // psi_0 = agent 1's column, psi_1 = twice agent 2's column.
  std::vector<float> w(2 * 13, 0.0f);
  for (int c = 0; c < 5; ++c) {
    w[1 + c] = static_cast<float>(c);
    w[13 + 7 + c] = 2.0f * c;
  }
  ASSERT_TRUE(scorer->kind().SetLinearForTest("psi", 0, w, {0.0f, 0.0f}).ok());
  // Agent 1: 0 -> 1, agent 2: 4 -> 3, twice in one episode.
  const Scored r = Score(*scorer, {{0, 4}, {0, 4}}, {{1, 3}, {1, 3}}, {false, false}, /*dry_run=*/false);
  // psi(S_t) = (0, 8), psi(S_t+1) = (1, 6): R = 1 + 4 = 5.
  EXPECT_NEAR(r.global[0], 5.0f, 1e-5);
  // d^1 = |(1, 8) - (0, 8)|^2 = 1, d^2 = |(0, 6) - (0, 8)|^2 = 4.
  EXPECT_NEAR(r.contributions[0], 1.0f, 1e-5);
  EXPECT_NEAR(r.contributions[1], 4.0f, 1e-5);
  EXPECT_NEAR(r.shares[1], 0.9525741f, 1e-5);  // 1 / (1 + e^-3).
  // First visit of each agent's cell: N_ep = 1.
  EXPECT_NEAR(r.agent_rewards[0], 0.2371293f, 1e-5);
  EXPECT_NEAR(r.agent_rewards[1], 4.7628707f, 1e-5);
  // Second visit in the same episode: divided by sqrt(2).
  EXPECT_NEAR(r.agent_rewards[2], 0.1676758f, 1e-5);
  EXPECT_NEAR(r.agent_rewards[3], 3.3678581f, 1e-5);
}

TEST_F(SfScorerTest, PsiConvergesToAnalyticSuccessorFeaturesOnAChain) {
  Use("1....T2\n");
  SfConfig sf;
  sf.gamma = 0.9;
  sf.target_update = 5;
  sf.learning_rate = 3e-3;
  auto scorer = Make("shared", sf);
  // Agent 1 walks 0 -> 1 -> 2 -> 3, where the episode terminates; agent 2 stays at 6.
  for (int i = 0; i < 2000; ++i) {
    Score(*scorer, {{0, 6}, {1, 6}, {2, 6}}, {{1, 6}, {2, 6}, {3, 6}}, {false, false, true}, false);
  }
  std::vector<std::vector<float>> phi;
  for (int cell = 0; cell < 3; ++cell) {
    const std::vector<int32_t> state = {0, cell, 6, 0};
    phi.push_back(scorer->kind().PhiForTest(state.data()));
  }
  const std::vector<int32_t> s0 = {0, 0, 6, 0};
  const std::vector<float> psi = scorer->kind().PsiForTest(s0.data());
  double error = 0, norm = 0;
  for (size_t f = 0; f < psi.size(); ++f) {
    const double analytic = phi[0][f] + 0.9 * phi[1][f] + 0.81 * phi[2][f];
    error += (psi[f] - analytic) * (psi[f] - analytic);
    norm += analytic * analytic;
  }
  EXPECT_GT(norm, 0.0);
  EXPECT_LT(std::sqrt(error), 0.05 * std::sqrt(norm)) << "psi did not converge to sum_k gamma^k phi";
}

TEST_F(SfScorerTest, IndependentCreditScoresEachAgentsOwnSuccessorFeatures) {
  auto scorer = Make("independent");
  const Scored r = Score(*scorer, {{0, 4}}, {{1, 4}}, {false}, false);
  EXPECT_GT(r.agent_rewards[0], 0.0f);   // Agent 1 moved.
  EXPECT_EQ(r.agent_rewards[1], 0.0f);   // Agent 2 stayed: same local state.
  EXPECT_NEAR(r.global[0], r.agent_rewards[0], 1e-6);
}

TEST_F(SfScorerTest, SnapshotRoundTripGivesIdenticalOutputs) {
  const std::string path = ::testing::TempDir() + "/sf_snapshot_" + std::to_string(getpid()) + ".pt";
  auto scorer = Make("imca");
  for (int i = 0; i < 5; ++i) Score(*scorer, {{0, 4}, {1, 4}}, {{1, 4}, {1, 3}}, {false, false}, false);
  ASSERT_TRUE(scorer->Save(path).ok());
  ScorerConfig config;
  config.credit = "imca";
  config.seed = 77;
  auto made = MakeScorer("sf", *scenario_, config);
  ASSERT_TRUE(made.ok());
  std::unique_ptr<CreditScorer> restored = *std::move(made);
  ASSERT_TRUE(restored->Load(path).ok());
  const Scored a = Score(*scorer, {{2, 4}}, {{2, 3}}, {false}, true);
  const Scored b = Score(*restored, {{2, 4}}, {{2, 3}}, {false}, true);
  EXPECT_EQ(a.global, b.global);
  EXPECT_EQ(a.contributions, b.contributions);
  auto other = Make("shared");
  EXPECT_EQ(other->Load(path).code(), absl::StatusCode::kFailedPrecondition);
  std::remove(path.c_str());
}

}  // namespace
}  // namespace imca::reward
