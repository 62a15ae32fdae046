// The actor against real in-process services that fail on cue, in the manner
// of LevelDB's SpecialEnv: a learner stream that drops an ack after the
// learner accepted the unroll, one that never acks, a reward server that is
// unavailable once and a scorer that fails once. The actor must deliver every
// unroll exactly once to training and count every answered Score once.
#include "actor/actor.h"

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <string>
#include <thread>

#include "common/env/env.h"
#include "common/rpc/grpc_util.h"
#include "google/protobuf/util/json_util.h"
#include "gtest/gtest.h"
#include "learner/algorithms/mappo/mappo_options.h"
#include "learner/learner.h"
#include "learner/learner_service.h"
#include "reward_server/make_scorer.h"
#include "reward_server/reward_service.h"
#include "reward_server/scorer_testing.h"

namespace imca {
namespace {

using PushStream = learner::LearnerServiceImpl::PushStream;

// The real PushUnrolls stream with hooks: `after_read` sees each request read
// and `before_write` each ack; either returning false ends the stream there
// (the learner service's loop sees the client gone).
class HookedStream final : public PushStream {
 public:
  HookedStream(PushStream* real, std::function<bool(const v1::PushUnrollsRequest&)> after_read,
               std::function<bool(const v1::PushUnrollsResponse&)> before_write)
      : real_(real), after_read_(std::move(after_read)), before_write_(std::move(before_write)) {}
  void SendInitialMetadata() override { real_->SendInitialMetadata(); }
  bool NextMessageSize(uint32_t* size) override { return real_->NextMessageSize(size); }
  bool Read(v1::PushUnrollsRequest* request) override { return real_->Read(request) && after_read_(*request); }
  using grpc::internal::WriterInterface<v1::PushUnrollsResponse>::Write;
  bool Write(const v1::PushUnrollsResponse& ack, grpc::WriteOptions options) override {
    return before_write_(ack) && real_->Write(ack, options);
  }

 private:
  PushStream* real_;
  const std::function<bool(const v1::PushUnrollsRequest&)> after_read_;
  const std::function<bool(const v1::PushUnrollsResponse&)> before_write_;
};

// The real learner service, whose PushUnrolls loses the ack of the learner's
// accepted unroll number `drop_ack_of` (the stream ends before it), and reads
// unroll number `hang_on` and then never answers until the client cancels.
class FlakyLearnerService final : public v1::LearnerService::Service {
 public:
  FlakyLearnerService(learner::Learner* learner, int drop_ack_of, int hang_on)
      : real_(learner), drop_ack_of_(drop_ack_of), hang_on_(hang_on) {}

  grpc::Status PushUnrolls(grpc::ServerContext* context,
                           grpc::ServerReaderWriter<v1::PushUnrollsResponse, v1::PushUnrollsRequest>* stream) override {
    HookedStream hooked(
        stream,
        [&](const v1::PushUnrollsRequest&) {
          if (++arrived_ != hang_on_) return true;
          while (!context->IsCancelled()) std::this_thread::sleep_for(std::chrono::milliseconds(10));
          return false;  // Injected: no ack until cancelled.
        },
        [&](const v1::PushUnrollsResponse& ack) {
          return ack.rejection() != v1::REJECTION_NONE || ++accepted_ != drop_ack_of_;
        });
    return real_.PushUnrollsInternal(context, &hooked);
  }
  grpc::Status GetPolicy(grpc::ServerContext* context, const v1::GetPolicyRequest* request,
                         v1::Policy* response) override {
    return real_.GetPolicy(context, request, response);
  }
  grpc::Status GetStatus(grpc::ServerContext* context, const v1::GetStatusRequest* request,
                         v1::LearnerStatus* response) override {
    return real_.GetStatus(context, request, response);
  }

 private:
  learner::LearnerServiceImpl real_;
  const int drop_ack_of_, hang_on_;
  std::atomic<int> arrived_{0}, accepted_{0};
};

// The real reward service, unavailable for the first Score call.
class FlakyRewardService final : public v1::RewardService::Service {
 public:
  explicit FlakyRewardService(reward::RewardServiceImpl* real) : real_(real) {}
  grpc::Status Score(grpc::ServerContext* context, const v1::ScoreRequest* request,
                     v1::ScoreResponse* response) override {
    if (calls_++ == 0) return grpc::Status(grpc::StatusCode::UNAVAILABLE, "injected: reward server restarting");
    return real_->Score(context, request, response);
  }

 private:
  reward::RewardServiceImpl* real_;
  std::atomic<int> calls_{0};
};

// A real scorer that fails its second call, before changing anything.
class FailingOnceScorer final : public testing::ForwardingScorer {
 public:
  explicit FailingOnceScorer(std::unique_ptr<reward::Scorer> real)
      : ForwardingScorer(real.get()), real_(std::move(real)) {}
  absl::Status Score(const reward::TransitionBatch& batch, bool dry_run, const reward::ScoreOutput& out) override {
    if (++calls_ == 2) return absl::InternalError("injected: scorer failed");
    return ForwardingScorer::Score(batch, dry_run, out);
  }

 private:
  std::unique_ptr<reward::Scorer> real_;
  std::atomic<int> calls_{0};
};

// A learner config for these tests: no checkpoints, a small network.
learner::LearnerConfig TestLearnerConfig() {
  learner::LearnerConfig config;
  config.checkpoint_every = 0;
  config.checkpoint_seconds = 0;
  learner::MutableOptions<learner::MappoOptions>(&config).ppo.hidden = 16;
  return config;
}

actor::ActorConfig SmallActor(int envs, int length) {
  actor::ActorConfig config;
  config.num_envs = envs;
  config.unroll_length = length;
  config.eval_envs = 1;
  config.rpc_timeout = std::chrono::milliseconds(2000);
  return config;
}

// `learner` and a count reward server (the binaries' default credit) on
// loopback ports, until destroyed.
class LoopbackServices {
 public:
  LoopbackServices(const env::Scenario* scenario, grpc::Service* learner) {
    auto scorer = reward::MakeScorer("count", *scenario, scorer_config_);
    EXPECT_TRUE(scorer.ok()) << scorer.status();
    if (!scorer.ok()) return;
    scorer_ = *std::move(scorer);
    reward_ = std::make_unique<reward::RewardServiceImpl>(scenario, scorer_.get(), "count", scorer_config_, "");
    auto learner_server = StartServer("127.0.0.1:0", {learner}, &learner_port_);
    auto reward_server = StartServer("127.0.0.1:0", {reward_.get()}, &reward_port_);
    EXPECT_TRUE(learner_server.ok() && reward_server.ok());
    if (!learner_server.ok() || !reward_server.ok()) return;
    learner_server_ = *std::move(learner_server);
    reward_server_ = *std::move(reward_server);
  }
  ~LoopbackServices() {
    if (learner_server_ != nullptr) learner_server_->Shutdown(DeadlineIn(std::chrono::seconds(1)));
    if (reward_server_ != nullptr) reward_server_->Shutdown(DeadlineIn(std::chrono::seconds(1)));
  }
  bool ok() const { return learner_server_ != nullptr && reward_server_ != nullptr; }
  // An actor of `config` talking to both.
  std::unique_ptr<actor::Actor> MakeActor(const env::Scenario* scenario, const actor::ActorConfig& config) const {
    return std::make_unique<actor::Actor>(scenario, config,
                                          MakeChannel("127.0.0.1:" + std::to_string(learner_port_)),
                                          MakeChannel("127.0.0.1:" + std::to_string(reward_port_)));
  }

 private:
  reward::ScorerConfig scorer_config_;
  std::unique_ptr<reward::Scorer> scorer_;
  std::unique_ptr<reward::RewardServiceImpl> reward_;
  int learner_port_ = 0, reward_port_ = 0;
  std::unique_ptr<grpc::Server> learner_server_, reward_server_;
};

TEST(ActorFaultTest, LostAcksHungStreamsAndFailedScoresLoseNothingAndTrainNothingTwice) {
  auto scenario = env::MakeScenario(env::ScenarioConfig{}, env::DefaultMapDir());
  ASSERT_TRUE(scenario.ok()) << scenario.status();
  constexpr int kEnvs = 16, kLength = 16, kIterations = 8;

  learner::LearnerConfig learner_config = TestLearnerConfig();
  learner_config.batch_steps = kEnvs * kLength;  // One unroll per iteration.
  learner_config.synchronous = false;
  learner_config.budget_steps = kIterations * kEnvs * kLength;
  learner_config.max_policy_lag = 100;
  auto learner = learner::Learner::Create(scenario->get(), learner_config);
  ASSERT_TRUE(learner.ok()) << learner.status();
  FlakyLearnerService learner_service(learner->get(), /*drop_ack_of=*/3, /*hang_on=*/6);

  reward::ScorerConfig scorer_config;
  scorer_config.credit = "imca";
  auto real_scorer = reward::MakeScorer("count", **scenario, scorer_config);
  ASSERT_TRUE(real_scorer.ok()) << real_scorer.status();
  FailingOnceScorer scorer(*std::move(real_scorer));
  reward::RewardServiceImpl reward_impl(scenario->get(), &scorer, "count", scorer_config, "");
  FlakyRewardService reward_service(&reward_impl);

  int learner_port = 0, reward_port = 0;
  auto learner_server = StartServer("127.0.0.1:0", {&learner_service}, &learner_port);
  auto reward_server = StartServer("127.0.0.1:0", {&reward_service}, &reward_port);
  ASSERT_TRUE(learner_server.ok() && reward_server.ok());
  std::thread trainer([&] { EXPECT_TRUE((*learner)->Run().ok()); });

  actor::ActorConfig config;
  config.actor_id = "actor-7";
  config.num_envs = kEnvs;
  config.unroll_length = kLength;
  config.eval_envs = 2;
  config.rpc_timeout = std::chrono::milliseconds(2000);
  config.ack_timeout = std::chrono::milliseconds(300);
  config.status_file = (std::filesystem::temp_directory_path() /
                        ("actor_status_" + std::to_string(getpid()) + ".json")).string();
  actor::Actor actor(scenario->get(), config, MakeChannel("127.0.0.1:" + std::to_string(learner_port)),
                     MakeChannel("127.0.0.1:" + std::to_string(reward_port)));
  const auto started = std::chrono::steady_clock::now();
  EXPECT_TRUE(actor.Run().ok());
  const double ran = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  trainer.join();

  // The final status has the time of every phase of the loop, retries
  // included, and together no more than Run() took.
  v1::ActorStatus written;
  {
    std::ifstream in(config.status_file);
    std::string line;
    ASSERT_TRUE(std::getline(in, line));
    google::protobuf::util::JsonParseOptions options;
    options.ignore_unknown_fields = true;  // "time".
    ASSERT_TRUE(google::protobuf::util::JsonStringToMessage(line, &written, options).ok()) << line;
  }
  std::filesystem::remove(config.status_file);
  EXPECT_EQ(written.state(), v1::ActorStatus::DONE);
  ASSERT_EQ(written.phase_seconds_size(), actor::Actor::kNumPhases);
  double phases = 0;
  for (const char* phase : {"acting", "scoring", "pushing", "choosing_policy"}) {
    ASSERT_TRUE(written.phase_seconds().contains(phase)) << phase;
    EXPECT_GT(written.phase_seconds().at(phase), 0.0) << phase;
    phases += written.phase_seconds().at(phase);
  }
  EXPECT_LE(phases, ran);

  const v1::LearnerStatus status = (*learner)->Status();
  EXPECT_TRUE(status.done());
  EXPECT_EQ(status.env_steps(), learner_config.budget_steps);
  // The lost ack's unroll was resent and recognised; the hung one was resent
  // and accepted (the learner never had it).
  EXPECT_EQ(status.unrolls_duplicate(), 1);
  EXPECT_GE(actor.unrolls_resent(), 2);
  EXPECT_EQ(status.actor_incarnations(), 1);
  // Every unroll the actor delivered was accepted once: none lost, none twice.
  EXPECT_EQ(status.unrolls_received(), actor.unrolls_pushed());
  // The reward server counted each answered Score once: the injected
  // failures changed nothing and their unrolls were scored on the retry.
  EXPECT_EQ(reward_impl.Stats().transitions_scored(), actor.transitions_scored());
  EXPECT_EQ(reward_impl.Stats().requests_served(), actor.transitions_scored() / (kEnvs * kLength));
  (*learner_server)->Shutdown(DeadlineIn(std::chrono::seconds(1)));
  (*reward_server)->Shutdown(DeadlineIn(std::chrono::seconds(1)));
}

// Stop() from another thread ends Run() with OK while the learner still
// trains, without the process-wide shutdown (so tests after this one run).
TEST(ActorTest, StopEndsRunFromAnotherThread) {
  auto scenario = env::MakeScenario(env::ScenarioConfig{}, env::DefaultMapDir());
  ASSERT_TRUE(scenario.ok()) << scenario.status();
  learner::LearnerConfig learner_config = TestLearnerConfig();
  learner_config.batch_steps = 8 * 16;
  learner_config.synchronous = true;  // The actor also waits for policies.
  learner_config.actors = 1;
  auto learner = learner::Learner::Create(scenario->get(), learner_config);
  ASSERT_TRUE(learner.ok()) << learner.status();
  learner::LearnerServiceImpl learner_service(learner->get());
  LoopbackServices services(scenario->get(), &learner_service);
  ASSERT_TRUE(services.ok());
  std::thread trainer([&] { EXPECT_TRUE((*learner)->Run().ok()); });
  std::unique_ptr<actor::Actor> acting_actor = services.MakeActor(scenario->get(), SmallActor(8, 16));
  actor::Actor& actor = *acting_actor;
  std::atomic<bool> finished{false};
  std::thread acting([&] {
    const absl::Status status = actor.Run();
    EXPECT_TRUE(status.ok()) << status;
    finished = true;
  });
  while ((*learner)->Status().policy_version() < 3 && !finished) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_FALSE(finished) << "the actor stopped by itself";
  actor.Stop();
  acting.join();
  EXPECT_FALSE(ShutdownRequested());
  EXPECT_FALSE((*learner)->Status().done());
  EXPECT_GE(actor.unrolls_pushed(), 3);
  (*learner)->Stop();
  trainer.join();
}

// The learner an actor talks to is replaced by one that starts over at
// version 0 (a restart with no checkpoint to go on from), in synchronous
// mode: the actor's unrolls in hand are ahead of it, and after refetching
// its policy the actor must act the new learner's whole share of version 0.
class SwitchingLearnerService final : public v1::LearnerService::Service {
 public:
  // Switches once `switch_when` holds.
  SwitchingLearnerService(learner::Learner* first, learner::Learner* second, std::function<bool()> switch_when)
      : first_(first),
        second_(second),
        first_service_(first),
        second_service_(second),
        switch_when_(std::move(switch_when)) {}

  grpc::Status PushUnrolls(grpc::ServerContext* context,
                           grpc::ServerReaderWriter<v1::PushUnrollsResponse, v1::PushUnrollsRequest>* stream) override {
    // A stream open when the switch comes ends there (the learner is gone);
    // the actor's next one reaches the second learner.
    HookedStream hooked(
        stream, [this](const v1::PushUnrollsRequest&) { return !Switch(); },
        [](const v1::PushUnrollsResponse&) { return true; });
    Switch();
    return (switched_ ? second_service_ : first_service_).PushUnrollsInternal(context, &hooked);
  }
  grpc::Status GetPolicy(grpc::ServerContext* context, const v1::GetPolicyRequest* request,
                         v1::Policy* response) override {
    Switch();
    return (switched_ ? second_service_ : first_service_).GetPolicy(context, request, response);
  }
  grpc::Status GetStatus(grpc::ServerContext* context, const v1::GetStatusRequest* request,
                         v1::LearnerStatus* response) override {
    return (switched_ ? second_service_ : first_service_).GetStatus(context, request, response);
  }

 private:
  // True the first time: switch_when held and the first learner is gone.
  bool Switch() {
    if (switched_ || !switch_when_()) return false;
    bool expected = false;
    if (!switched_.compare_exchange_strong(expected, true)) return false;
    first_->Stop();
    return true;
  }

  learner::Learner* first_;
  learner::Learner* second_;
  learner::LearnerServiceImpl first_service_, second_service_;
  const std::function<bool()> switch_when_;
  std::atomic<bool> switched_{false};
};

// One actor with `actor_config` against `first`, then, once `switch_when`
// holds, against `second` (as a learner restarted on the same address), with
// a count reward server; both learners train meanwhile. True if the actor
// finished (its learner's budget done) within `limit`; else it is stopped.
bool ActsThroughARestart(const env::Scenario* scenario, learner::Learner* first, learner::Learner* second,
                         std::function<bool()> switch_when, const actor::ActorConfig& actor_config,
                         std::chrono::seconds limit) {
  SwitchingLearnerService service(first, second, std::move(switch_when));
  LoopbackServices services(scenario, &service);
  if (!services.ok()) return false;
  std::thread first_trainer([&] { EXPECT_TRUE(first->Run().ok()); });
  std::thread second_trainer([&] { EXPECT_TRUE(second->Run().ok()); });
  std::unique_ptr<actor::Actor> acting_actor = services.MakeActor(scenario, actor_config);
  actor::Actor& actor = *acting_actor;
  std::atomic<bool> finished{false};
  std::thread acting([&] {
    EXPECT_TRUE(actor.Run().ok());
    finished = true;
  });
  const auto deadline = std::chrono::steady_clock::now() + limit;
  while (!finished && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  const bool done = finished;
  if (!done) {
    actor.Stop();
    second->Stop();
  }
  acting.join();
  first->Stop();
  first_trainer.join();
  second_trainer.join();
  return done;
}

TEST(ActorFaultTest, ASynchronousActorFollowsALearnerThatStartedOver) {
  auto scenario = env::MakeScenario(env::ScenarioConfig{}, env::DefaultMapDir());
  ASSERT_TRUE(scenario.ok()) << scenario.status();
  constexpr int kEnvs = 8, kLength = 16, kUnrollsPerVersion = 3;
  learner::LearnerConfig config = TestLearnerConfig();
  config.synchronous = true;
  config.batch_steps = kUnrollsPerVersion * kEnvs * kLength;
  config.budget_steps = 100 * config.batch_steps;
  auto first = learner::Learner::Create(scenario->get(), config);
  config.budget_steps = 4 * config.batch_steps;
  auto second = learner::Learner::Create(scenario->get(), config);
  ASSERT_TRUE(first.ok() && second.ok());
  actor::ActorConfig actor_config = SmallActor(kEnvs, kLength);
  actor_config.sync_unrolls = kUnrollsPerVersion;
  EXPECT_TRUE(ActsThroughARestart(
      scenario->get(), first->get(), second->get(), [&] { return (*first)->Status().policy_version() >= 3; },
      actor_config, std::chrono::seconds(60)))
      << "the actor waits for a version the new learner cannot train (it lacks the unrolls)";
  EXPECT_TRUE((*second)->Status().done());
  EXPECT_EQ((*second)->Status().env_steps(), 4 * config.batch_steps);
  EXPECT_GE((*first)->Status().policy_version(), 3);
}

// A learner killed right after a checkpoint resumes at the very version the
// actors hold, without the unrolls of it they delivered to the old one: a
// synchronous actor sees the new incarnation and acts its share again
// (else each side waits for the other for ever).
TEST(ActorFaultTest, ASynchronousActorActsItsShareAgainForALearnerRestartedAtItsVersion) {
  auto scenario = env::MakeScenario(env::ScenarioConfig{}, env::DefaultMapDir());
  ASSERT_TRUE(scenario.ok()) << scenario.status();
  constexpr int kEnvs = 8, kLength = 16, kShareUnrolls = 2;
  constexpr int64_t kShare = kShareUnrolls * kEnvs * kLength;
  learner::LearnerConfig config = TestLearnerConfig();
  config.synchronous = true;
  config.actors = 2;  // The first waits for a second actor that never comes: it never trains.
  config.batch_steps = 2 * kShare;
  auto first = learner::Learner::Create(scenario->get(), config);
  config.actors = 1;
  config.batch_steps = kShare;
  config.budget_steps = 2 * kShare;
  auto second = learner::Learner::Create(scenario->get(), config);
  ASSERT_TRUE(first.ok() && second.ok());
  // The switch comes once the actor's whole share of version 0 is queued;
  // the actor asks each policy for its share (sync_unrolls -1).
  EXPECT_TRUE(ActsThroughARestart(
      scenario->get(), first->get(), second->get(),
      [&] { return (*first)->Status().unrolls_received() >= kShareUnrolls; }, SmallActor(kEnvs, kLength),
      std::chrono::seconds(30)))
      << "the actor waits for version 1 while the restarted learner waits for its share of 0";
  EXPECT_EQ((*first)->Status().policy_version(), 0);
  EXPECT_TRUE((*second)->Status().done());
  EXPECT_EQ((*second)->Status().env_steps(), 2 * kShare);
}

}  // namespace
}  // namespace imca
