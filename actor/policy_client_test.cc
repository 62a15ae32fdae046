// The PolicyClient against a real gRPC server on loopback whose LearnerService
// answers from a script (a narrow fake: the policies are a real learner's).
#include "actor/policy_client.h"

#include <chrono>
#include <memory>
#include <thread>

#include "absl/synchronization/mutex.h"
#include "common/env/featurizer.h"
#include "common/rpc/grpc_util.h"
#include "gtest/gtest.h"
#include "learner/algorithms/mappo/mappo_options.h"
#include "learner/learner.h"

namespace imca::actor {
namespace {

// Serves `policy` (its version and incarnation settable) the way the real
// service does: the policy if its version >= min_version, else only its
// version; a long poll waits for a newer version up to wait_ms.
class ScriptedLearner final : public v1::LearnerService::Service {
 public:
  void Set(const v1::Policy& policy, uint64_t incarnation) {
    absl::MutexLock lock(&mu_);
    policy_ = policy;
    policy_.set_learner_incarnation(incarnation);
  }
  void SetDone() {
    absl::MutexLock lock(&mu_);
    done_ = true;
  }

  grpc::Status GetPolicy(grpc::ServerContext*, const v1::GetPolicyRequest* request, v1::Policy* response) override {
    absl::MutexLock lock(&mu_);
    auto newer = [&] {
      mu_.AssertHeld();
      return policy_.version() >= request->min_version();
    };
    mu_.AwaitWithTimeout(absl::Condition(&newer), absl::Milliseconds(request->wait_ms()));
    if (newer()) {
      *response = policy_;
    } else {
      response->set_version(policy_.version());
      response->set_learner_incarnation(policy_.learner_incarnation());
    }
    return grpc::Status::OK;
  }
  grpc::Status GetStatus(grpc::ServerContext*, const v1::GetStatusRequest*, v1::LearnerStatus* response) override {
    absl::MutexLock lock(&mu_);
    response->set_done(done_);
    return grpc::Status::OK;
  }

 private:
  absl::Mutex mu_;
  v1::Policy policy_ ABSL_GUARDED_BY(mu_);
  bool done_ ABSL_GUARDED_BY(mu_) = false;
};

class PolicyClientTest : public ::testing::Test {
 protected:
  void SetUp() override {
    auto scenario = env::MakeScenario(env::ScenarioConfig{}, env::DefaultMapDir());
    ASSERT_TRUE(scenario.ok());
    scenario_ = *std::move(scenario);
    learner::LearnerConfig config;
    learner::MutableOptions<learner::MappoOptions>(&config).ppo.hidden = 8;
    config.checkpoint_every = 0;
    config.checkpoint_seconds = 0;
    auto learner = learner::Learner::Create(scenario_.get(), config);
    ASSERT_TRUE(learner.ok()) << learner.status();
    policy_ = *(*learner)->CurrentPolicy();
    int port = 0;
    auto server = StartServer("127.0.0.1:0", {&service_}, &port);
    ASSERT_TRUE(server.ok()) << server.status();
    server_ = *std::move(server);
    stub_ = v1::LearnerService::NewStub(MakeChannel("127.0.0.1:" + std::to_string(port)));
  }
  void TearDown() override { server_->Shutdown(DeadlineIn(std::chrono::seconds(1))); }

  v1::Policy Version(int64_t version) const {
    v1::Policy p = policy_;
    p.set_version(version);
    return p;
  }
  std::unique_ptr<PolicyClient> Client(PolicyClient::Admit admit = nullptr) {
    PolicyClientOptions options;
    options.rpc_timeout = std::chrono::milliseconds(2000);
    return std::make_unique<PolicyClient>(stub_.get(), *scenario_, options,
                                          &stop_, std::move(admit), nullptr);
  }

  std::unique_ptr<env::Scenario> scenario_;
  v1::Policy policy_;
  ScriptedLearner service_;
  std::unique_ptr<grpc::Server> server_;
  std::unique_ptr<v1::LearnerService::Stub> stub_;
  StopSignal stop_;
};

TEST_F(PolicyClientTest, TakesTheNewestAndKeepsItWhenNothingIsNewer) {
  service_.Set(Version(0), 1);
  auto client = Client();
  EXPECT_EQ(client->policy(), nullptr);
  ASSERT_TRUE(client->Refresh(/*wait=*/true));
  EXPECT_EQ(client->version(), 0);
  ASSERT_TRUE(client->Refresh(/*wait=*/false));  // Not modified.
  EXPECT_EQ(client->version(), 0);
  service_.Set(Version(3), 1);
  ASSERT_TRUE(client->Refresh(/*wait=*/false));
  EXPECT_EQ(client->version(), 3);
  EXPECT_TRUE(client->error().ok());
}

TEST_F(PolicyClientTest, AwaitBlocksUntilTheVersionIsPublished) {
  service_.Set(Version(0), 1);
  auto client = Client();
  ASSERT_TRUE(client->Refresh(/*wait=*/true));
  std::thread publisher([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    service_.Set(Version(1), 1);
  });
  EXPECT_TRUE(client->Await(1));
  EXPECT_EQ(client->version(), 1);
  publisher.join();
}

TEST_F(PolicyClientTest, FollowsALearnerThatWentBack) {
  service_.Set(Version(4), 1);
  auto client = Client();
  ASSERT_TRUE(client->Await(4));
  // Restarted from an older checkpoint: older than ours.
  service_.Set(Version(2), 1);
  ASSERT_TRUE(client->Await(5));
  EXPECT_EQ(client->version(), 2);
  // Restarted at our very version, by a new incarnation.
  service_.Set(Version(2), 9);
  ASSERT_TRUE(client->Await(3));
  EXPECT_EQ(client->version(), 2);
}

TEST_F(PolicyClientTest, RefusesAPolicyThatDoesNotFitOrIsNotAdmitted) {
  v1::Policy wrong = Version(0);
  wrong.mutable_tensors(0)->clear_data();
  service_.Set(wrong, 1);
  auto client = Client();
  EXPECT_FALSE(client->Refresh(/*wait=*/true));
  EXPECT_EQ(client->error().code(), absl::StatusCode::kInternal);
  EXPECT_NE(client->error().message().find("does not fit coop_nav"), std::string::npos) << client->error();
  EXPECT_EQ(client->policy(), nullptr);

  service_.Set(Version(0), 1);
  auto picky = Client([](const v1::Policy&) { return absl::FailedPreconditionError("not a whole share"); });
  EXPECT_FALSE(picky->Refresh(/*wait=*/true));
  EXPECT_EQ(picky->error().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_EQ(picky->policy(), nullptr);
}

TEST_F(PolicyClientTest, StopEndsAWaitForAVersionThatNeverComes) {
  service_.Set(Version(0), 1);
  auto client = Client();
  ASSERT_TRUE(client->Refresh(/*wait=*/true));
  std::thread stopper([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    stop_.Stop();
  });
  EXPECT_FALSE(client->Await(1));  // Without the stop, it long-polls for ever.
  EXPECT_TRUE(client->error().ok());
  stopper.join();
}

TEST_F(PolicyClientTest, AwaitEndsWhenTheLearnerIsDone) {
  service_.Set(Version(0), 1);
  service_.SetDone();
  auto client = Client();
  ASSERT_TRUE(client->Refresh(/*wait=*/true));
  EXPECT_FALSE(client->Await(1));
  EXPECT_TRUE(client->error().ok());
}

}  // namespace
}  // namespace imca::actor
