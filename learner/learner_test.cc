#include "learner/algorithms/mappo/mappo.h"
#include "learner/learner.h"
#include "learner/push_testing.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <thread>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "common/env/env.h"
#include "common/env/featurizer.h"
#include "common/metrics/metrics_testing.h"
#include "common/protocol/test_unrolls.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace imca::learner {
namespace {

using ::testing::HasSubstr;

class LearnerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    auto scenario = env::MakeScenario(env::ScenarioConfig{}, env::DefaultMapDir());
    ASSERT_TRUE(scenario.ok());
    scenario_ = *std::move(scenario);
    run_dir_ = ::testing::TempDir() + "/learner_test_" + std::to_string(getpid());
    std::filesystem::remove_all(run_dir_);
    config_.batch_steps = 256;
    config_.synchronous = false;  // The tests of synchronous admission say so.
    config_.run_dir = run_dir_;
    config_.checkpoint_every = 0;
    config_.max_policy_lag = 1;
  }

  v1::Unroll Unroll(int64_t version, uint64_t seed) {
    v1::Unroll u = testing::RandomUnroll(*scenario_, 16, 16, seed);
    u.set_policy_version(version);
    for (int i = 0; i < u.intrinsic_rewards_size(); ++i) u.set_intrinsic_rewards(i, 0.01f * (i % 7));
    return u;
  }

  std::unique_ptr<env::Scenario> scenario_;
  std::string run_dir_;
  LearnerConfig config_;
};

TEST_F(LearnerTest, RejectsBadUnrollsWithTheFieldName) {
  auto learner = Learner::Create(scenario_.get(), config_);
  ASSERT_TRUE(learner.ok()) << learner.status();
  v1::Unroll bad = Unroll(0, 1);
  bad.mutable_intrinsic_rewards()->RemoveLast();
  absl::StatusOr<PushOutcome> status = (*learner)->Push(bad);
  EXPECT_EQ(RejectionOf(status), v1::REJECTION_INVALID);
  EXPECT_THAT(Why(status), HasSubstr("unroll.intrinsic_rewards"));
  bad = Unroll(0, 1);
  bad.set_behaviour_log_probs(0, 0.5f);
  EXPECT_THAT(Why((*learner)->Push(bad)), HasSubstr("unroll.behaviour_log_probs[0]"));
  bad = Unroll(0, 1);
  bad.add_global_rewards(0.5f);  // Diagnostics are optional, but sized when present.
  EXPECT_THAT(Why((*learner)->Push(bad)), HasSubstr("unroll.global_rewards"));
  bad = Unroll(0, 1);
  bad.mutable_contributions()->Resize(bad.intrinsic_rewards_size(), std::nanf(""));
  EXPECT_THAT(Why((*learner)->Push(bad)), HasSubstr("unroll.contributions"));
  bad = Unroll(7, 1);  // Ahead of the learner (it resumed from an older checkpoint): retryable.
  status = (*learner)->Push(bad);
  EXPECT_EQ(RejectionOf(status), v1::REJECTION_AHEAD);
  EXPECT_THAT(Why(status), HasSubstr("ahead: unroll.policy_version"));
  EXPECT_EQ((*learner)->Status().unrolls_rejected(), 5);
  EXPECT_EQ((*learner)->Status().unrolls_received(), 0);
}

TEST_F(LearnerTest, CapsTheBatchFeatureMemory) {
  auto probe = Learner::Create(scenario_.get(), config_);
  ASSERT_TRUE(probe.ok()) << probe.status();
  const int64_t per_step = (*probe)->IterationBytes(1);
  EXPECT_EQ((*probe)->IterationBytes(10), 10 * per_step);
  EXPECT_EQ((*probe)->IterationBytes(int64_t{1} << 62), std::numeric_limits<int64_t>::max());
  probe->reset();

  config_.max_batch_bytes = per_step * config_.batch_steps - 1;
  auto too_small = Learner::Create(scenario_.get(), config_);
  EXPECT_EQ(too_small.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(too_small.status().message(), HasSubstr("batch_steps"));

  // Room for batch_steps - 1 steps plus one 16x16 unroll, not a 16x32 one.
  config_.max_batch_bytes = per_step * (config_.batch_steps - 1 + 16 * 16);
  auto learner = Learner::Create(scenario_.get(), config_);
  ASSERT_TRUE(learner.ok()) << learner.status();
  EXPECT_TRUE(Accepted((*learner)->Push(Unroll(0, 1))));
  v1::Unroll big = testing::RandomUnroll(*scenario_, 16, 32, 2);
  const absl::StatusOr<PushOutcome> status = (*learner)->Push(big);
  EXPECT_EQ(RejectionOf(status), v1::REJECTION_OVER_CAP);
  EXPECT_THAT(Why(status), HasSubstr("unroll.length * unroll.num_envs = 512 steps"));
  EXPECT_EQ((*learner)->Status().unrolls_received(), 1);
  EXPECT_EQ((*learner)->Status().unrolls_rejected(), 1);
}

TEST_F(LearnerTest, TrainsPublishesDropsStaleAndCheckpoints) {
  config_.budget_steps = 3 * 256;
  auto learner = Learner::Create(scenario_.get(), config_);
  ASSERT_TRUE(learner.ok()) << learner.status();
  Learner* l = learner->get();
  EXPECT_EQ(l->CurrentPolicy()->version(), 0);
  std::thread trainer([l] { EXPECT_TRUE(l->Run().ok()); });
  uint64_t seed = 1;
  ASSERT_TRUE(Accepted(l->Push(Unroll(0, seed++))));
  while (l->Status().policy_version() < 1) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  ASSERT_TRUE(Accepted(l->Push(Unroll(1, seed++))));
  while (l->Status().policy_version() < 2) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  // Version 0 is now 2 behind with max_policy_lag 1: dropped and counted.
  const absl::StatusOr<PushOutcome> stale = l->Push(Unroll(0, seed++));
  EXPECT_EQ(RejectionOf(stale), v1::REJECTION_STALE);
  EXPECT_THAT(Why(stale), HasSubstr("stale"));
  ASSERT_TRUE(Accepted(l->Push(Unroll(2, seed++))));
  trainer.join();
  const v1::LearnerStatus status = l->Status();
  EXPECT_TRUE(status.done());
  EXPECT_EQ(status.policy_version(), 3);
  EXPECT_EQ(status.env_steps(), 3 * 256);
  EXPECT_EQ(status.unrolls_dropped_stale(), 1);
  // After the budget, pushes learn that it is done (actors stop on this).
  EXPECT_EQ(l->Push(Unroll(3, seed++)).status().code(), absl::StatusCode::kOutOfRange);
  EXPECT_EQ(l->CurrentPolicy()->tensors_size(), 6);

  // metrics.csv has a header and one row per iteration.
  std::ifstream metrics(run_dir_ + "/metrics.csv");
  std::string line;
  int lines = 0;
  while (std::getline(metrics, line)) ++lines;
  EXPECT_EQ(lines, 4);

  // The final policy is also on disk as a serialized imca.v1.Policy.
  std::ifstream policy_file(run_dir_ + "/policy.pb", std::ios::binary);
  v1::Policy on_disk;
  ASSERT_TRUE(on_disk.ParseFromIstream(&policy_file));
  EXPECT_EQ(on_disk.version(), 3);

  // A new learner resumes from the final checkpoint with the same policy.
  auto resumed = Learner::Create(scenario_.get(), config_);
  ASSERT_TRUE(resumed.ok());
  ASSERT_TRUE((*resumed)->Restore(run_dir_ + "/checkpoints").ok());
  EXPECT_EQ((*resumed)->Status().policy_version(), 3);
  EXPECT_EQ((*resumed)->Status().env_steps(), 3 * 256);
  // Its counters go on from the checkpoint's (a restart is not a burst of training).
  EXPECT_THAT((*resumed)->metrics().Text(), HasSubstr("\nimca_learner_env_steps_total 768\n"));
  EXPECT_THAT((*resumed)->metrics().Text(), HasSubstr("\nimca_learner_iterations_total 3\n"));
  const v1::Policy& a = *l->CurrentPolicy();
  const v1::Policy& b = *(*resumed)->CurrentPolicy();
  ASSERT_EQ(a.tensors_size(), b.tensors_size());
  for (int i = 0; i < a.tensors_size(); ++i) {
    EXPECT_EQ(a.tensors(i).data().size(), b.tensors(i).data().size());
    EXPECT_TRUE(std::equal(a.tensors(i).data().begin(), a.tensors(i).data().end(), b.tensors(i).data().begin()));
  }
}

using metrics::testing::SampleValue;

TEST_F(LearnerTest, PrometheusFamiliesCountRefusalsByReasonAndEachTrainedUnrollsLag) {
  config_.budget_steps = 2 * 256;
  auto learner = Learner::Create(scenario_.get(), config_);
  ASSERT_TRUE(learner.ok()) << learner.status();
  Learner* l = learner->get();
  // Every reason's series exists from the start, at zero.
  for (const char* reason : {"stale", "ahead", "over_cap", "duplicate", "invalid"}) {
    EXPECT_EQ(SampleValue(l->metrics().Text(), absl::StrCat("imca_learner_unrolls_dropped_total{reason=\"", reason, "\"}")),
              0)
        << reason;
  }
  v1::Unroll bad = Unroll(0, 9);
  bad.set_num_agents(7);
  EXPECT_TRUE(RejectionOf(l->Push(bad)) == v1::REJECTION_INVALID);
  EXPECT_EQ(RejectionOf(l->Push(Unroll(5, 10))), v1::REJECTION_AHEAD);  // Ahead of version 0.
  std::thread trainer([l] { EXPECT_TRUE(l->Run().ok()); });
  ASSERT_TRUE(Accepted(l->Push(Unroll(0, 1))));
  while (l->Status().policy_version() < 1) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  // Queued at version 1, acted with 0: trained with a lag of 1.
  ASSERT_TRUE(Accepted(l->Push(Unroll(0, 2))));
  trainer.join();
  const std::string text = l->metrics().Text();
  EXPECT_EQ(SampleValue(text, R"(imca_learner_unrolls_dropped_total{reason="invalid"})"), 1) << text;
  EXPECT_EQ(SampleValue(text, R"(imca_learner_unrolls_dropped_total{reason="ahead"})"), 1);
  EXPECT_EQ(SampleValue(text, R"(imca_learner_unrolls_dropped_total{reason="stale"})"), 0);
  EXPECT_EQ(SampleValue(text, "imca_learner_unrolls_received_total"), 2);
  EXPECT_EQ(SampleValue(text, R"(imca_learner_policy_lag_versions_bucket{le="0"})"), 1);
  EXPECT_EQ(SampleValue(text, R"(imca_learner_policy_lag_versions_bucket{le="1"})"), 2);
  EXPECT_EQ(SampleValue(text, R"(imca_learner_policy_lag_versions_bucket{le="+Inf"})"), 2);
  EXPECT_EQ(SampleValue(text, "imca_learner_policy_lag_versions_sum"), 1);
  EXPECT_EQ(SampleValue(text, "imca_learner_policy_lag_versions_count"), 2);
  // The metrics.csv columns' families hold the last row's values.
  EXPECT_EQ(SampleValue(text, "imca_learner_iterations_total"), 2);
  EXPECT_EQ(SampleValue(text, "imca_learner_env_steps_total"), 512);
  EXPECT_EQ(SampleValue(text, "imca_learner_policy_version"), 2);
  EXPECT_EQ(SampleValue(text, "imca_learner_budget_done"), 1);
  EXPECT_EQ(SampleValue(text, "imca_learner_queue_depth"), 0);
  EXPECT_EQ(SampleValue(text, "imca_learner_actor_ids"), 1);
  std::ifstream metrics(run_dir_ + "/metrics.csv");
  std::string header;
  ASSERT_TRUE(std::getline(metrics, header));
  EXPECT_EQ(header, CsvHeader("mappo", scenario_->num_agents()));
}

TEST_F(LearnerTest, MetricsOfAnotherVersionAreKeptApart) {
  // A run folder from a version with other metrics columns (e.g. resumed
  // across an upgrade): its rows move to metrics.old.csv, the new file gets
  // the current header and rows of matching width.
  std::filesystem::create_directories(run_dir_);
  std::ofstream(run_dir_ + "/metrics.csv") << "iteration,env_steps\n1,256\n";
  config_.budget_steps = 256;
  auto learner = Learner::Create(scenario_.get(), config_);
  ASSERT_TRUE(learner.ok()) << learner.status();
  Learner* l = learner->get();
  std::thread trainer([l] { EXPECT_TRUE(l->Run().ok()); });
  ASSERT_TRUE(Accepted(l->Push(Unroll(0, 1))));
  trainer.join();
  std::ifstream old_file(run_dir_ + "/metrics.old.csv");
  std::string line;
  ASSERT_TRUE(std::getline(old_file, line));
  EXPECT_EQ(line, "iteration,env_steps");
  std::ifstream metrics(run_dir_ + "/metrics.csv");
  std::string header, row;
  ASSERT_TRUE(std::getline(metrics, header));
  ASSERT_TRUE(std::getline(metrics, row));
  EXPECT_THAT(header, HasSubstr(",global_reward,contribution_abs,success_episodes,train_success_episodes,entropy,"
                                "updates,policy_loss,value_loss,approx_kl,clip_fraction,behaviour_kl,voi_reward,"
                                "share_1,share_2"));
  EXPECT_EQ(std::count(header.begin(), header.end(), ','), std::count(row.begin(), row.end(), ','));
  EXPECT_THAT(row, ::testing::Not(HasSubstr("nan")));  // MAPPO reported each of its own columns.
}

TEST_F(LearnerTest, EdtiNeedsInfluencesAndTrainsItsInteractionHead) {
  config_.budget_steps = 2 * 256;
  MutableOptions<MappoOptions>(&config_).edti = true;
  auto two_heads = Learner::Create(scenario_.get(), config_);
  ASSERT_FALSE(two_heads.ok());
  EXPECT_THAT(two_heads.status().message(), HasSubstr("edti needs 3"));
  MutableOptions<MappoOptions>(&config_).ppo.value_heads = 3;
  auto learner = Learner::Create(scenario_.get(), config_);
  ASSERT_TRUE(learner.ok()) << learner.status();
  Learner* l = learner->get();
  const int n = scenario_->num_agents();
  const absl::StatusOr<PushOutcome> missing = l->Push(Unroll(0, 1));
  EXPECT_EQ(RejectionOf(missing), v1::REJECTION_INVALID);
  EXPECT_THAT(Why(missing), HasSubstr("unroll.influences is empty"));
  auto with_influences = [&](int64_t version, uint64_t seed) {
    v1::Unroll u = Unroll(version, seed);
    const int64_t size = int64_t{u.length()} * u.num_envs() * n * n;
    for (int64_t i = 0; i < size; ++i) u.add_influences((i % (n + 1)) == 0 ? 0.0f : 0.25f);  // Diagonal 0.
    return u;
  };
  v1::Unroll short_one = with_influences(0, 2);
  short_one.mutable_influences()->RemoveLast();
  EXPECT_THAT(Why(l->Push(short_one)), HasSubstr("unroll.influences"));
  ASSERT_TRUE(Accepted(l->Push(with_influences(0, 3))));
  ASSERT_TRUE(Accepted(l->Push(with_influences(0, 4))));  // Lag 1 by the time it trains: allowed.
  ASSERT_TRUE(l->Run().ok());
  EXPECT_EQ(l->Status().env_steps(), 2 * 256);
  // The interaction rewards reach metrics.csv: the partner-reward term alone
  // is 0.1 * the partner's curiosity here, so the mean is positive.
  std::ifstream metrics(run_dir_ + "/metrics.csv");
  std::string header, row;
  ASSERT_TRUE(std::getline(metrics, header));
  ASSERT_TRUE(std::getline(metrics, row));
  const std::vector<std::string> names = absl::StrSplit(header, ',');
  const int voi = std::find(names.begin(), names.end(), "voi_reward") - names.begin();
  ASSERT_LT(voi, static_cast<int>(names.size()));
  EXPECT_NE(std::stod(std::vector<std::string>(absl::StrSplit(row, ','))[voi]), 0.0);
}

TEST_F(LearnerTest, SynchronousTrainsOnlyOnThePolicyItStartsFrom) {
  config_.synchronous = true;
  config_.max_policy_lag = 4;  // Ignored: synchronous means lag 0.
  config_.budget_steps = 2 * 256;
  auto learner = Learner::Create(scenario_.get(), config_);
  ASSERT_TRUE(learner.ok()) << learner.status();
  Learner* l = learner->get();
  int64_t woke_with = -1;
  std::thread waiter([&] { woke_with = l->WaitForPolicy(1, absl::Seconds(60))->version(); });
  ASSERT_TRUE(Accepted(l->Push(Unroll(0, 1))));  // 256 steps: version 0's batch is full.
  const absl::StatusOr<PushOutcome> surplus = l->Push(Unroll(0, 2));
  EXPECT_EQ(RejectionOf(surplus), v1::REJECTION_STALE);
  EXPECT_THAT(Why(surplus), HasSubstr("stale: the batch of policy version 0 is full"));
  std::thread trainer([l] { EXPECT_TRUE(l->Run().ok()); });
  waiter.join();  // Woken by the publication of version 1.
  EXPECT_EQ(woke_with, 1);
  // Version 0 is only one behind, but a synchronous learner takes no lag.
  const absl::StatusOr<PushOutcome> old = l->Push(Unroll(0, 3));
  EXPECT_THAT(Why(old), HasSubstr("stale: policy version 0 is not the synchronous learner's 1"));
  ASSERT_TRUE(Accepted(l->Push(Unroll(1, 4))));
  trainer.join();
  EXPECT_EQ(l->Status().env_steps(), 2 * 256);
  EXPECT_EQ(l->Status().unrolls_dropped_stale(), 2);
  // Every iteration trained at lag 0.
  std::ifstream metrics(run_dir_ + "/metrics.csv");
  std::string header, row;
  ASSERT_TRUE(std::getline(metrics, header));
  const std::vector<std::string> names = absl::StrSplit(header, ',');
  const int lag = std::find(names.begin(), names.end(), "policy_lag") - names.begin();
  int rows = 0;
  while (std::getline(metrics, row)) {
    EXPECT_EQ(std::vector<std::string>(absl::StrSplit(row, ','))[lag], "0.000") << row;
    ++rows;
  }
  EXPECT_EQ(rows, 2);
  // A wait for a version that never comes ends at its timeout with the newest.
  EXPECT_EQ(l->WaitForPolicy(100, absl::Milliseconds(10))->version(), 2);
}

TEST_F(LearnerTest, CriticInputsAndTimeLimitOptionsTrain) {
  config_.budget_steps = 256;
  MutableOptions<MappoOptions>(&config_).critic_input = CriticInput::kJointObs;
  config_.time_limit = TimeLimit::kTerminal;
  MutableOptions<MappoOptions>(&config_).ppo.value_heads = 1;
  auto learner = Learner::Create(scenario_.get(), config_);
  ASSERT_TRUE(learner.ok()) << learner.status();
  const env::Featurizer featurizer(*scenario_);
  EXPECT_EQ(MappoCriticDim(*scenario_, config_), 2 * featurizer.obs_dim() + 2);
  Learner* l = learner->get();
  std::thread trainer([l] { EXPECT_TRUE(l->Run().ok()); });
  ASSERT_TRUE(Accepted(l->Push(Unroll(0, 1))));
  trainer.join();
  EXPECT_EQ(l->Status().policy_version(), 1);
  CriticInput input = CriticInput::kState;
  std::string error;
  EXPECT_TRUE(AbslParseFlag("joint_obs", &input, &error));
  EXPECT_EQ(input, CriticInput::kJointObs);
  TimeLimit limit = TimeLimit::kBootstrap;
  EXPECT_FALSE(AbslParseFlag("never", &limit, &error));
  EXPECT_THAT(error, HasSubstr("bootstrap or terminal"));
}

TEST_F(LearnerTest, ResentUnrollsAreDroppedAcrossARestart) {
  config_.budget_steps = 2 * 256;
  auto learner = Learner::Create(scenario_.get(), config_);
  ASSERT_TRUE(learner.ok()) << learner.status();
  Learner* l = learner->get();
  auto tagged = [&](uint64_t incarnation, int64_t sequence, uint64_t seed) {
    v1::Unroll u = Unroll(0, seed);
    u.set_actor_id("actor-1");
    u.set_incarnation(incarnation);
    u.set_sequence(sequence);
    return u;
  };
  ASSERT_TRUE(Accepted(l->Push(tagged(5, 1, 1))));
  // The same unroll again (its ack was lost): recognised, not queued.
  const absl::StatusOr<PushOutcome> again = l->Push(tagged(5, 1, 1));
  EXPECT_EQ(RejectionOf(again), v1::REJECTION_DUPLICATE);
  EXPECT_THAT(Why(again), HasSubstr("duplicate: unroll 1 of actor-1"));
  // A restarted actor (new incarnation) numbers from 1 again: accepted.
  ASSERT_TRUE(Accepted(l->Push(tagged(6, 1, 2))));
  v1::LearnerStatus status = l->Status();
  EXPECT_EQ(status.unrolls_received(), 2);
  EXPECT_EQ(status.unrolls_duplicate(), 1);
  EXPECT_EQ(status.actor_incarnations(), 2);
  EXPECT_EQ(status.queue_depth(), 2);
  ASSERT_TRUE(l->Run().ok());  // Trains both, checkpoints at the end.

  // A learner restarted from that checkpoint still knows what it accepted.
  auto restarted = Learner::Create(scenario_.get(), config_);
  ASSERT_TRUE(restarted.ok());
  ASSERT_TRUE((*restarted)->Restore(run_dir_ + "/checkpoints").ok());
  v1::Unroll resent = tagged(6, 1, 2);
  resent.set_policy_version(2);
  EXPECT_EQ(RejectionOf((*restarted)->Push(resent)), v1::REJECTION_DUPLICATE);
  resent.set_sequence(2);
  EXPECT_TRUE(Accepted((*restarted)->Push(resent)));
  EXPECT_EQ((*restarted)->Status().env_steps(), 2 * 256);
}

TEST_F(LearnerTest, PoisonUnrollsAreRefusedAndExtremeOnesTrain) {
  config_.budget_steps = 256;
  auto learner = Learner::Create(scenario_.get(), config_);
  ASSERT_TRUE(learner.ok()) << learner.status();
  Learner* l = learner->get();
  // The two unrolls that ended the learner from a Python client: a log-prob
  // no float probability has, and one a float holds but that is not the log
  // of the recorded probability.
  for (const float poison : {-1e38f, -90.0f}) {
    v1::Unroll bad = Unroll(0, 1);
    bad.set_behaviour_log_probs(0, poison);
    const absl::StatusOr<PushOutcome> status = l->Push(bad);
    EXPECT_EQ(RejectionOf(status), v1::REJECTION_INVALID) << poison;
    EXPECT_THAT(Why(status), HasSubstr("unroll.behaviour_log_probs[0]")) << poison;
    EXPECT_THAT(Why(status), HasSubstr("is not the log of action_probs[0]")) << poison;
  }
  v1::Unroll huge = Unroll(0, 1);
  huge.set_rewards(3, 1e30f);
  EXPECT_THAT(Why(l->Push(huge)), HasSubstr("unroll.rewards[3]: 1e+30 is outside [-1e6, 1e6]"));
  huge = Unroll(0, 1);
  huge.set_intrinsic_rewards(0, -2e6f);
  EXPECT_THAT(Why(l->Push(huge)), HasSubstr("unroll.intrinsic_rewards[0]"));
  // Consistent but extreme: the recorded action had probability 1e-12, the
  // floor, so the learner's ratio is ~1e11 before its bound. Trains.
  v1::Unroll extreme = Unroll(0, 2);
  const int a_count = scenario_->num_actions();
  for (int row = 0; row < extreme.actions_size(); ++row) {
    const int taken = extreme.actions(row);
    for (int j = 0; j < a_count; ++j) {
      extreme.set_action_probs(row * a_count + j, j == taken ? 0.0f : 1.0f / (a_count - 1));
    }
    extreme.set_behaviour_log_probs(row, std::log(1e-12f));
    extreme.set_rewards(row, row % 2 == 0 ? 1e5f : -1e5f);
  }
  ASSERT_TRUE(Accepted(l->Push(extreme)));
  ASSERT_TRUE(l->Run().ok());
  const v1::LearnerStatus status = l->Status();
  EXPECT_EQ(status.policy_version(), 1);
  EXPECT_EQ(status.batches_dropped(), 0);
  EXPECT_EQ(status.minibatches_skipped(), 0);
  for (const v1::NamedTensor& t : l->CurrentPolicy()->tensors()) {
    for (float w : t.data()) ASSERT_TRUE(std::isfinite(w)) << t.name();
  }
}

TEST_F(LearnerTest, CheckpointsByTimeAndFallsBackPastADamagedOne) {
  config_.budget_steps = 3 * 256;
  config_.checkpoint_every = 0;
  config_.checkpoint_seconds = 1e-6;  // After every iteration.
  config_.max_policy_lag = 10;
  auto learner = Learner::Create(scenario_.get(), config_);
  ASSERT_TRUE(learner.ok()) << learner.status();
  Learner* l = learner->get();
  for (uint64_t seed = 1; seed <= 3; ++seed) ASSERT_TRUE(Accepted(l->Push(Unroll(0, seed))));
  ASSERT_TRUE(l->Run().ok());
  const std::string dir = run_dir_ + "/checkpoints";
  for (const char* stem : {"/ckpt-00000001", "/ckpt-00000002", "/ckpt-00000003"}) {
    EXPECT_TRUE(std::filesystem::exists(dir + stem + ".meta")) << stem;
  }
  // A .pt without its .meta (a crash between the two) is not a checkpoint.
  std::filesystem::copy_file(dir + "/ckpt-00000003.pt", dir + "/ckpt-00000009.pt");
  EXPECT_EQ(CheckpointStore(dir).Newest().value(), dir + "/ckpt-00000003.meta");
  // A damaged newest checkpoint costs one interval, not the run.
  std::filesystem::resize_file(dir + "/ckpt-00000003.pt", 100);
  auto restarted = Learner::Create(scenario_.get(), config_);
  ASSERT_TRUE(restarted.ok());
  ASSERT_TRUE((*restarted)->Restore(dir).ok());
  EXPECT_EQ((*restarted)->Status().policy_version(), 2);
  EXPECT_EQ((*restarted)->Status().env_steps(), 2 * 256);
}

TEST_F(LearnerTest, StopWakesBlockedPushers) {
  config_.queue_capacity = 1;
  auto learner = Learner::Create(scenario_.get(), config_);
  ASSERT_TRUE(learner.ok());
  Learner* l = learner->get();
  ASSERT_TRUE(Accepted(l->Push(Unroll(0, 1))));  // Fills the queue; nobody trains.
  EXPECT_EQ(l->Status().pushers_waiting(), 0);
  std::thread pusher([l, this] { EXPECT_EQ(l->Push(Unroll(0, 2)).status().code(), absl::StatusCode::kUnavailable); });
  // Stop only once the pusher is blocked on the full queue, so that the test
  // is of the wake-up and not of a Push that saw the stop first.
  while (l->Status().pushers_waiting() == 0) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  EXPECT_EQ(l->Status().queue_depth(), 1);
  l->Stop();
  pusher.join();
  EXPECT_EQ(l->Status().pushers_waiting(), 0);
}

}  // namespace
}  // namespace imca::learner
