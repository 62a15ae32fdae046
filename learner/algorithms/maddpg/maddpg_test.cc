#include "learner/algorithms/maddpg/maddpg.h"

#include <torch/torch.h>

#include <filesystem>
#include <map>

#include "common/base/rng.h"
#include "common/env/env.h"
#include "common/protocol/test_unrolls.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "learner/algorithms/maddpg/maddpg_internal.h"
#include "learner/algorithms/registry.h"
#include "learner/iteration_metrics.h"
#include "learner/learner.h"

namespace imca::learner {
namespace {

using ::testing::HasSubstr;

TEST(GumbelSoftmaxTest, ForwardIsTheArgmaxOneHotAndGradientTheSoftSamples) {
  const torch::Tensor logits = torch::tensor({{0.5f, -1.0f, 2.0f}, {1.0f, 1.0f, -3.0f}}).requires_grad_(true);
  const torch::Tensor uniform = torch::tensor({{0.9f, 0.2f, 0.1f}, {0.3f, 0.6f, 0.5f}});
  const torch::Tensor y = internal::GumbelSoftmaxHard(logits, uniform);
  // g = -log(-log u); argmax of logits + g per row, worked by hand:
  // row 0: 0.5 + 2.250 = 2.750, -1 - 0.476 = -1.476, 2 - 0.834 = 1.166 -> 0;
  // row 1: 1 - 0.186 = 0.814, 1 + 0.672 = 1.672, -3 + 0.367 = -2.633 -> 1.
  EXPECT_TRUE(torch::equal(y.detach(), torch::tensor({{1.0f, 0.0f, 0.0f}, {0.0f, 1.0f, 0.0f}})));
  // Straight through: d(w . y)/d logits is that of the soft sample.
  const torch::Tensor w = torch::tensor({{1.0f, 2.0f, 3.0f}, {-1.0f, 0.5f, 2.0f}});
  (w * y).sum().backward();
  const torch::Tensor grad = logits.grad().clone();
  const torch::Tensor logits2 = logits.detach().clone().requires_grad_(true);
  const torch::Tensor soft = torch::softmax(logits2 - torch::log(-torch::log(uniform)), -1);
  (w * soft).sum().backward();
  EXPECT_TRUE(torch::allclose(grad, logits2.grad(), 1e-6, 1e-6)) << grad << logits2.grad();
  EXPECT_GT(grad.abs().sum().item<float>(), 0.0f);
}

class MaddpgTest : public ::testing::Test {
 protected:
  void SetUp() override {
    env::ScenarioConfig sc;
    sc.name = "pass";  // Two agents, four actions.
    auto scenario = env::MakeScenario(sc, env::DefaultMapDir());
    ASSERT_TRUE(scenario.ok()) << scenario.status();
    scenario_ = *std::move(scenario);
    config_ = *DefaultLearnerConfig("pass", "maddpg");  // Asynchronous, as MADDPG runs.
    MutableOptions<MaddpgConfig>(&config_).batch_size = 8;
    MutableOptions<MaddpgConfig>(&config_).learning_starts = 8;
    MutableOptions<MaddpgConfig>(&config_).buffer_transitions = 64;
    config_.gamma = 0.9;
    Rng rng(3);
    state_.resize(scenario_->state_size());
    scenario_->Reset(rng, state_.data());
    other_.resize(scenario_->state_size());
    scenario_->Reset(rng, other_.data());
  }

  std::unique_ptr<Maddpg> Make(const LearnerConfig& config) {
    auto maddpg = Maddpg::Create(scenario_.get(), config);
    EXPECT_TRUE(maddpg.ok()) << maddpg.status();
    return maddpg.ok() ? *std::move(maddpg) : nullptr;
  }

  Maddpg::Transition Step(std::vector<int32_t> actions, std::vector<float> rewards, bool done) {
    return Maddpg::Transition{state_, other_, std::move(actions), std::move(rewards), done};
  }

  std::unique_ptr<env::Scenario> scenario_;
  LearnerConfig config_;
  std::vector<int32_t> state_, other_;
};

TEST_F(MaddpgTest, CriticTargetIsRewardPlusDiscountedTargetQ) {
  // A terminal transition's target is its reward.
  auto maddpg = Make(config_);
  maddpg->InsertForTest(Step({1, 2}, {0.5f, -2.0f}, /*done=*/true));
  absl::StatusOr<std::vector<float>> y = maddpg->CriticTargetsForTest(0);
  ASSERT_TRUE(y.ok()) << y.status();
  EXPECT_THAT(*y, ::testing::ElementsAre(0.5f, -2.0f));
  // Otherwise y - r = gamma * Q'(o', a'): two learners with the same seed
  // (same target networks and noise) and gamma 0.9 and 0.45 differ by half.
  LearnerConfig half = config_;
  half.gamma = 0.45;
  auto a = Make(config_), b = Make(half);
  a->InsertForTest(Step({1, 2}, {0.5f, -2.0f}, false));
  b->InsertForTest(Step({1, 2}, {0.5f, -2.0f}, false));
  const std::vector<float> ya = *a->CriticTargetsForTest(0), yb = *b->CriticTargetsForTest(0);
  const float r[2] = {0.5f, -2.0f};
  for (int i = 0; i < 2; ++i) {
    EXPECT_NE(ya[i], r[i]) << i;  // The bootstrap is there...
    EXPECT_NEAR(yb[i] - r[i], 0.5f * (ya[i] - r[i]), 1e-6) << i;  // ...and discounted by gamma.
  }
}

TEST_F(MaddpgTest, ReplayIsUniformAndFifoOnceFull) {
  auto maddpg = Make(config_);
  for (int i = 0; i < 70; ++i) maddpg->InsertForTest(Step({i % 4, 0}, {float(i), 0.0f}, true));
  EXPECT_EQ(maddpg->replay_size(), 64);  // Capacity; the oldest six were overwritten.
  // Slots 0..5 now hold transitions 64..69: their targets are those rewards.
  EXPECT_EQ((*maddpg->CriticTargetsForTest(0))[0], 64.0f);
  EXPECT_EQ((*maddpg->CriticTargetsForTest(5))[0], 69.0f);
  EXPECT_EQ((*maddpg->CriticTargetsForTest(6))[0], 6.0f);
  // Sampling: fresh learners with the same seed and replay.
  auto first = Make(config_), again = Make(config_);
  for (int i = 0; i < 70; ++i) {
    first->InsertForTest(Step({i % 4, 0}, {float(i), 0.0f}, true));
    again->InsertForTest(Step({i % 4, 0}, {float(i), 0.0f}, true));
  }
  std::map<int64_t, int> counts;
  const std::vector<int64_t> indices = first->SampleIndicesForTest(64000);
  for (int64_t i : indices) counts[i]++;
  ASSERT_EQ(counts.size(), 64u);
  EXPECT_EQ(counts.begin()->first, 0);
  EXPECT_EQ(counts.rbegin()->first, 63);
  for (const auto& [index, count] : counts) {
    EXPECT_GT(count, 800) << index;  // Expected 1000, std ~31.
    EXPECT_LT(count, 1200) << index;
  }
  // The same seed samples the same indices.
  EXPECT_EQ(again->SampleIndicesForTest(64000), indices);
}

TEST_F(MaddpgTest, FindsTheOptimalJointActionOfACooperativeMatrixGame) {
  // One-step game in one state: both agents get 1 for the joint action
  // (2, 3), 0.5 for (0, 0), else 0. The replay holds every joint action
  // equally often; the greedy joint action must become (2, 3).
  for (bool share : {true, false}) {
    LearnerConfig config = config_;
    MutableOptions<MaddpgConfig>(&config).share_parameters = share;
    MutableOptions<MaddpgConfig>(&config).buffer_transitions = 160;
    MutableOptions<MaddpgConfig>(&config).batch_size = 160;
    MutableOptions<MaddpgConfig>(&config).learning_starts = 160;
    auto maddpg = Make(config);
    for (int repeat = 0; repeat < 10; ++repeat) {
      for (int a0 = 0; a0 < 4; ++a0) {
        for (int a1 = 0; a1 < 4; ++a1) {
          const float r = (a0 == 2 && a1 == 3) ? 1.0f : (a0 == 0 && a1 == 0) ? 0.5f : 0.0f;
          maddpg->InsertForTest(Step({a0, a1}, {r, r}, true));
        }
      }
    }
    for (int step = 0; step < 400; ++step) ASSERT_TRUE(maddpg->UpdateForTest().ok());
    const std::vector<float> p = maddpg->ProbabilitiesForTest(state_);
    EXPECT_GT(p[0 * 4 + 2], 0.9f) << "share " << share << ": agent 0 " << p[0] << " " << p[1] << " " << p[2] << " " << p[3];
    EXPECT_GT(p[1 * 4 + 3], 0.9f) << "share " << share << ": agent 1 " << p[4] << " " << p[5] << " " << p[6] << " " << p[7];
  }
}

TEST_F(MaddpgTest, RejectsBadConfigsNamingTheFlag) {
  LearnerConfig bad = config_;
  MutableOptions<MaddpgConfig>(&bad).batch_size = 0;
  EXPECT_THAT(Maddpg::Create(scenario_.get(), bad).status().message(), HasSubstr("--maddpg_batch"));
  bad = config_;
  MutableOptions<MaddpgConfig>(&bad).tau = 0;
  EXPECT_THAT(Maddpg::Create(scenario_.get(), bad).status().message(), HasSubstr("--maddpg_tau"));
  bad = config_;
  MutableOptions<MaddpgConfig>(&bad).updates_per_step = 0;
  EXPECT_EQ(Maddpg::Create(scenario_.get(), bad).status().code(), absl::StatusCode::kInvalidArgument);
  bad = config_;
  MutableOptions<MaddpgConfig>(&bad).buffer_transitions = 1000000;
  MutableOptions<MaddpgConfig>(&bad).learning_starts = 1000;
  bad.max_batch_bytes = 1000000;  // 1 MB: far below a million transitions.
  EXPECT_THAT(Maddpg::Create(scenario_.get(), bad).status().message(), HasSubstr("--max_batch_mb"));
  bad = config_;
  MutableOptions<MaddpgConfig>(&bad).learning_starts = 1000;  // Over the buffer.
  EXPECT_THAT(Maddpg::Create(scenario_.get(), bad).status().message(), HasSubstr("--maddpg_learning_starts"));
}

TEST_F(MaddpgTest, AddTakesExactlyTheUpdatesTheRatioAllows) {
  LearnerConfig config = config_;
  MutableOptions<MaddpgConfig>(&config).buffer_transitions = 4096;
  MutableOptions<MaddpgConfig>(&config).learning_starts = 100;
  MutableOptions<MaddpgConfig>(&config).updates_per_step = 0.05;
  auto maddpg = Make(config);
  // 16 steps x 8 envs = 128 transitions per unroll: the first gives
  // (128 - 99) * 0.05 = 1.45 -> 1 update, the second 1.45 + 6.4 -> 7 in all.
  FeaturisedUnroll u;
  u.unroll = testing::RandomUnroll(*scenario_, 16, 8, 1);
  ASSERT_TRUE(maddpg->Add(u).ok());
  EXPECT_EQ(maddpg->updates(), 1);
  u.unroll = testing::RandomUnroll(*scenario_, 16, 8, 2);
  ASSERT_TRUE(maddpg->Add(u).ok());
  EXPECT_EQ(maddpg->updates(), 7);
  EXPECT_EQ(maddpg->replay_size(), 256);
  absl::StatusOr<IterationStats> stats = maddpg->Train();
  ASSERT_TRUE(stats.ok());
  EXPECT_EQ(stats->updates, 7);
  // Its own columns by name, each of them (learner/iteration_metrics.h).
  std::vector<std::string> names;
  for (const auto& [name, value] : stats->values) {
    names.push_back(name);
    EXPECT_TRUE(std::isfinite(value)) << name;
  }
  EXPECT_EQ(names, AlgorithmColumnNames("maddpg"));
  EXPECT_EQ(stats->values.back().second, 256);  // replay_size.
  EXPECT_GT(stats->entropy, 0.0);
}

TEST_F(MaddpgTest, CheckpointRoundTripRestoresPolicyAndRatioAndRefusesOtherShapes) {
  auto maddpg = Make(config_);
  for (int i = 0; i < 16; ++i) maddpg->InsertForTest(Step({i % 4, (i / 4) % 4}, {1.0f, 0.0f}, i % 2 == 0));
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(maddpg->UpdateForTest().ok());
  const std::string path = ::testing::TempDir() + "/maddpg_test.pt";
  ASSERT_TRUE(maddpg->Save(path).ok());
  LearnerConfig other_seed = config_;
  other_seed.seed = 99;
  auto restored = Make(other_seed);
  EXPECT_NE(restored->ProbabilitiesForTest(state_), maddpg->ProbabilitiesForTest(state_));
  ASSERT_TRUE(restored->Load(path).ok());
  EXPECT_EQ(restored->ProbabilitiesForTest(state_), maddpg->ProbabilitiesForTest(state_));
  EXPECT_EQ(restored->updates(), 5);
  EXPECT_EQ(restored->ExportPolicy(3).SerializeAsString(), maddpg->ExportPolicy(3).SerializeAsString());
  LearnerConfig wider = config_;
  MutableOptions<MaddpgConfig>(&wider).hidden = 32;
  auto mismatched = Make(wider);
  EXPECT_EQ(mismatched->Load(path).code(), absl::StatusCode::kInvalidArgument);
  std::filesystem::remove(path);
}

TEST_F(MaddpgTest, LearnerTrainsMaddpgAndPublishesReluPolicies) {
  LearnerConfig config = config_;
  MutableOptions<MaddpgConfig>(&config).buffer_transitions = 4096;
  MutableOptions<MaddpgConfig>(&config).learning_starts = 256;
  MutableOptions<MaddpgConfig>(&config).batch_size = 64;
  config.batch_steps = 256;
  config.budget_steps = 1024;
  config.run_dir = ::testing::TempDir() + "/maddpg_learner_test";
  std::filesystem::remove_all(config.run_dir);
  auto learner = Learner::Create(scenario_.get(), config);
  ASSERT_TRUE(learner.ok()) << learner.status();
  EXPECT_EQ((*learner)->CurrentPolicy()->architecture(), v1::Policy::MLP_RELU);
  std::thread pusher([&] {
    for (int i = 0; i < 8; ++i) {
      v1::Unroll u = testing::RandomUnroll(*scenario_, 16, 8, 10 + i);
      u.set_policy_version((*learner)->CurrentPolicy()->version());
      if (!(*learner)->Push(std::move(u)).ok()) break;
    }
  });
  ASSERT_TRUE((*learner)->Run().ok());
  pusher.join();
  EXPECT_EQ((*learner)->Status().env_steps(), 1024);
  EXPECT_EQ((*learner)->Status().policy_version(), 4);
  // metrics.csv has the MADDPG columns filled: (1024 - 255) * 0.01 -> 7 updates.
  std::ifstream metrics(config.run_dir + "/metrics.csv");
  std::string header, row, last;
  std::getline(metrics, header);
  while (std::getline(metrics, row)) last = row;
  EXPECT_THAT(header, HasSubstr("updates,actor_loss,critic_loss,replay_size"));
  EXPECT_THAT(last, HasSubstr(",1024,"));
  EXPECT_THAT(last, ::testing::Not(HasSubstr("nan")));
  // A restarted learner resumes MADDPG from the final checkpoint: same
  // version, steps and published policy (its replay refills).
  auto restarted = Learner::Create(scenario_.get(), config);
  ASSERT_TRUE(restarted.ok()) << restarted.status();
  ASSERT_TRUE((*restarted)->Restore(config.run_dir + "/checkpoints").ok());
  EXPECT_EQ((*restarted)->Status().env_steps(), 1024);
  EXPECT_EQ((*restarted)->CurrentPolicy()->SerializeAsString(), (*learner)->CurrentPolicy()->SerializeAsString());
  // A MAPPO learner refuses MADDPG's checkpoint rather than misreading it.
  LearnerConfig mappo = config;
  mappo.algo = "mappo";
  mappo.options.reset();
  auto other = Learner::Create(scenario_.get(), mappo);
  ASSERT_TRUE(other.ok()) << other.status();
  EXPECT_FALSE((*other)->Restore(config.run_dir + "/checkpoints").ok());
  std::filesystem::remove_all(config.run_dir);
}

TEST_F(MaddpgTest, AStopMidIterationCountsAndPublishesWhatWasTrained) {
  // MADDPG trains as it adds: a stop after two of an iteration's eight
  // unrolls counts those 256 steps and publishes the weights they trained.
  LearnerConfig config = config_;
  MutableOptions<MaddpgConfig>(&config).buffer_transitions = 4096;
  MutableOptions<MaddpgConfig>(&config).learning_starts = 64;
  config.batch_steps = 1024;
  config.max_policy_lag = 0;  // On-policy only: old unrolls are not dropped.
  auto learner = Learner::Create(scenario_.get(), config);
  ASSERT_TRUE(learner.ok()) << learner.status();
  Learner* l = learner->get();
  std::thread trainer([l] { EXPECT_TRUE(l->Run().ok()); });
  for (int i = 0; i < 2; ++i) {
    v1::Unroll u = testing::RandomUnroll(*scenario_, 16, 8, 30 + i);
    u.set_policy_version(0);
    ASSERT_TRUE(l->Push(std::move(u)).ok());
  }
  // Once the training thread has taken both (queue empty), the second is
  // added before it looks for a third and finds the stop.
  while (l->Status().queue_depth() > 0) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  l->Stop();
  trainer.join();
  EXPECT_EQ(l->Status().env_steps(), 256);
  EXPECT_EQ(l->Status().policy_version(), 1);
}

}  // namespace
}  // namespace imca::learner
