// EITI / EDTI influence counts (docs/baselines.md, "What the server counts") against numbers worked
// by hand for 2 agents on a 5-cell line, and the learner-facing outputs.
#include "reward_server/novelty/influence_novelty.h"

#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <unistd.h>

#include "common/env/env.h"
#include "gtest/gtest.h"
#include "reward_server/make_scorer.h"
#include "reward_server/scorer_testing.h"

namespace imca::reward {
namespace {

constexpr int kN = 2;
constexpr int32_t kLeft = env::kLeft, kRight = env::kRight, kStay = env::kStay;

// One transition: (cell, action, reached cell) of agents 0 and 1, and the
// step count of the state it leaves (0: a reset state).
struct Step {
  int32_t s0, a0, next0, s1, a1, next1;
  int32_t t = 5;
};

struct Result {
  std::vector<float> global, contributions, shares, rewards, influences;
};

class InfluenceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    scenario_ = ::imca::testing::TextScenario();
    ASSERT_NE(scenario_, nullptr);
  }

  std::unique_ptr<CreditScorer> Make(const std::string& kind, bool log_form = false) {
    ScorerConfig config;
    config.credit = "independent";
    InfluenceConfig influence;
    influence.log_form = log_form;
    auto scorer = MakeScorer(kind, *scenario_, config, influence);
    EXPECT_TRUE(scorer.ok()) << scorer.status();
    return *std::move(scorer);
  }

  // Scores `steps` as `envs` envs x steps.size() / envs time steps (time-major).
  Result Score(Scorer& scorer, const std::vector<Step>& steps, int envs = 1, bool dry_run = false) {
    const int64_t N = steps.size();
    std::vector<int32_t> states, next_states, actions;
    for (const Step& s : steps) {
      states.insert(states.end(), {0, s.s0, s.s1, s.t});
      next_states.insert(next_states.end(), {0, s.next0, s.next1, s.t + 1});
      actions.insert(actions.end(), {s.a0, s.a1});
    }
    std::vector<float> probs(N * kN * 5, 0.2f);
    std::vector<int64_t> episodes(N, 1);
    const TransitionBatch batch{N, N / envs, envs, 4, states.data(), next_states.data(), actions.data(),
                                probs.data(), episodes.data(), nullptr, 3};
    Result r;
    r.global.resize(N);
    r.contributions.resize(N * kN);
    r.shares.resize(N * kN);
    r.rewards.resize(N * kN);
    ScoreOutput out{r.global.data(), r.contributions.data(), r.shares.data(), r.rewards.data()};
    if (scorer.ReturnsInfluences()) {
      r.influences.resize(N * kN * kN);
      out.influences = r.influences.data();
    }
    EXPECT_TRUE(scorer.Score(batch, dry_run, out).ok());
    return r;
  }

  std::unique_ptr<env::Scenario> scenario_;
};

// Agent 1 steps left from cell 4. Under agent 0's "stay" it first reaches 3,
// then under "right" it is blocked (stays on 4), then under "stay" blocked too.
const std::vector<Step> kWorked = {
    {0, kStay, 0, 4, kLeft, 3},   // c_{0->1} = 1 - (1/1) / (1/1) = 0
    {0, kRight, 1, 4, kLeft, 4},  // c_{0->1} = 1 - (1/2) / (1/1) = 0.5
    {0, kStay, 0, 4, kLeft, 4},   // c_{0->1} = 1 - (2/3) / (1/2) = -1/3
};

TEST_F(InfluenceTest, InfluenceAndEitiBonusMatchHandWorkedNumbers) {
  auto eiti = Make("eiti");
  const Result r = Score(*eiti, kWorked);
  // r_i = eta / sqrt(N_i(s'_i) + 1) + beta_t * c_{i->j}, eta = beta_t = 10.
  // Agent 0 reaches cells 0, 1, 0 (counts before 0, 0, 1); agent 1 reaches 3, 4, 4.
  const float root2 = static_cast<float>(std::sqrt(2.0));
  EXPECT_FLOAT_EQ(r.rewards[0 * kN + 0], 10.0f);
  EXPECT_FLOAT_EQ(r.rewards[1 * kN + 0], 10.0f + 10.0f * 0.5f);
  EXPECT_NEAR(r.rewards[2 * kN + 0], 10.0f / root2 + 10.0f * (-1.0f / 3.0f), 1e-5);
  // Agent 0's own moves are the same under any action of agent 1: c_{1->0} = 0.
  EXPECT_FLOAT_EQ(r.rewards[0 * kN + 1], 10.0f);
  EXPECT_FLOAT_EQ(r.rewards[1 * kN + 1], 10.0f);
  EXPECT_NEAR(r.rewards[2 * kN + 1], 10.0f / root2, 1e-5);
  // Independent credit: the team sum and each agent's part of it.
  EXPECT_NEAR(r.global[1], 15.0f + 10.0f, 1e-5);
  EXPECT_NEAR(r.shares[1 * kN + 0], 15.0f / 25.0f, 1e-6);
}

TEST_F(InfluenceTest, LogFormIsThePapersPointwiseMutualInformation) {
  auto eiti = Make("eiti", /*log_form=*/true);
  const Result r = Score(*eiti, kWorked);
  const double root2 = std::sqrt(2.0);
  EXPECT_NEAR(r.rewards[1 * kN + 0], 10.0 + 10.0 * (std::log(1.0) - std::log(0.5)), 1e-4);
  EXPECT_NEAR(r.rewards[2 * kN + 0], 10.0 / root2 + 10.0 * (std::log(0.5) - std::log(2.0 / 3.0)), 1e-4);
}

TEST_F(InfluenceTest, EdtiReturnsEveryInfluenceAndOnlyTheCuriosityAsBonus) {
  auto edti = Make("edti");
  ASSERT_TRUE(edti->ReturnsInfluences());
  const Result r = Score(*edti, kWorked);
  ASSERT_EQ(r.influences.size(), 3u * kN * kN);
  auto c = [&](int row, int i, int j) { return r.influences[(row * kN + i) * kN + j]; };
  EXPECT_FLOAT_EQ(c(0, 0, 1), 0.0f);
  EXPECT_FLOAT_EQ(c(1, 0, 1), 0.5f);
  EXPECT_NEAR(c(2, 0, 1), -1.0f / 3.0f, 1e-6);
  for (int row = 0; row < 3; ++row) {
    EXPECT_FLOAT_EQ(c(row, 0, 0), 0.0f);
    EXPECT_FLOAT_EQ(c(row, 1, 1), 0.0f);
    EXPECT_FLOAT_EQ(c(row, 1, 0), 0.0f);
  }
  EXPECT_FLOAT_EQ(r.rewards[1 * kN + 0], 10.0f) << "EDTI's bonus from the server is the curiosity alone";
  EXPECT_NEAR(r.rewards[2 * kN + 0], 10.0f / std::sqrt(2.0f), 1e-5);
}

TEST_F(InfluenceTest, AStepsEnvsAreAllAddedBeforeAnyIsRead) {
  // Two envs at the same time step: after both are added each sees N(4, left) = 2.
  auto eiti = Make("eiti");
  const Result r = Score(*eiti, {{0, kStay, 0, 4, kLeft, 3}, {1, kStay, 1, 4, kLeft, 4}}, /*envs=*/2);
  EXPECT_FLOAT_EQ(r.rewards[0 * kN + 0], 10.0f + 10.0f * 0.5f);
  EXPECT_FLOAT_EQ(r.rewards[1 * kN + 0], 10.0f + 10.0f * 0.5f);
}

TEST_F(InfluenceTest, TransitionsOutOfAResetAreNeitherCountedNorRewarded) {
  auto eiti = Make("eiti");
  Step reset = kWorked[1];
  reset.t = 0;
  const Result first = Score(*eiti, {kWorked[0], reset});
  EXPECT_FLOAT_EQ(first.rewards[1 * kN + 0], 10.0f) << "no influence term, the curiosity still counts";
  // Not counted: the worked step 2 still sees N(4, left, 4) = 0 before it.
  const Result next = Score(*eiti, {kWorked[1]});
  EXPECT_NEAR(next.rewards[0], 10.0f / std::sqrt(2.0f) + 10.0f * 0.5f, 1e-5);
}

TEST_F(InfluenceTest, DryRunChangesNothing) {
  auto eiti = Make("eiti");
  const Result dry = Score(*eiti, kWorked, 1, /*dry_run=*/true);
  const Result real = Score(*eiti, kWorked);
  EXPECT_FLOAT_EQ(real.rewards[1 * kN + 0], 15.0f);
  EXPECT_FLOAT_EQ(dry.rewards[0], real.rewards[0]);
}

TEST_F(InfluenceTest, SnapshotRoundTripGivesIdenticalScores) {
  const std::string path = ::testing::TempDir() + "/influence_" + std::to_string(getpid()) + ".bin";
  auto eiti = Make("eiti");
  Score(*eiti, kWorked);
  ASSERT_TRUE(eiti->Save(path).ok());
  auto restored = Make("eiti");
  ASSERT_TRUE(restored->Load(path).ok());
  EXPECT_EQ(Score(*eiti, kWorked, 1, true).rewards, Score(*restored, kWorked, 1, true).rewards);
  // Written by EITI, refused by EDTI and by another log setting.
  EXPECT_EQ(Make("edti")->Load(path).code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_EQ(Make("eiti", true)->Load(path).code(), absl::StatusCode::kFailedPrecondition);
  std::remove(path.c_str());
}

TEST_F(InfluenceTest, OnlyIndependentCreditIsOffered) {
  for (std::string credit : {"shared", "imca"}) {
    ScorerConfig config;
    config.credit = credit;
    auto scorer = MakeScorer("edti", *scenario_, config);
    ASSERT_FALSE(scorer.ok());
    EXPECT_EQ(scorer.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_NE(scorer.status().message().find("it serves: none, independent)"), std::string::npos) << scorer.status();
  }
  ScorerConfig none;
  none.credit = "none";
  EXPECT_TRUE(MakeScorer("eiti", *scenario_, none).ok()) << "credit none: no bonus, like every kind";
}

}  // namespace
}  // namespace imca::reward
