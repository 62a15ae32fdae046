// Every refusal path of the secured services over real loopback sockets:
// no token, a wrong token, a plaintext client, a certificate of another CA,
// a missing client certificate, an oversized request, too many streams and a
// flooding client. Each gives its documented code (docs/security.md), and
// nothing is counted, stored or trained.
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "absl/synchronization/mutex.h"
#include "actor/actor.h"
#include "common/env/env.h"
#include "common/protocol/test_unrolls.h"
#include "common/rpc/grpc_util.h"
#include "common/rpc/transport.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "imca/v1/learner_service.grpc.pb.h"
#include "imca/v1/reward_service.grpc.pb.h"
#include "learner/algorithms/mappo/mappo_options.h"
#include "learner/learner.h"
#include "learner/learner_service.h"
#include "learner/push_testing.h"
#include "reward_server/make_scorer.h"
#include "reward_server/reward_service.h"
#include "reward_server/scorer_testing.h"

namespace imca {
namespace {

using ::testing::HasSubstr;

namespace fs = std::filesystem;

// A CA with a server certificate, client certificates actor-0 and actor-1,
// and a token, made by tools/make_certs.sh (what ./imca train --secure runs).
std::string MakeCerts(const std::string& dir) {
  const std::string command =
      std::string(IMCA_SOURCE_DIR) + "/tools/make_certs.sh " + dir + " actor-0 actor-1 >/dev/null 2>&1";
  EXPECT_EQ(std::system(command.c_str()), 0) << command;
  return dir;
}

void WriteFile(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

class SecurityTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    root_ = new std::string(::testing::TempDir() + "/security_test_" + std::to_string(getpid()));
    fs::remove_all(*root_);
    MakeCerts(*root_ + "/a");
    MakeCerts(*root_ + "/b");  // Another CA.
  }
  static void TearDownTestSuite() {
    fs::remove_all(*root_);
    delete root_;
  }

  void SetUp() override {
    auto scenario = env::MakeScenario(env::ScenarioConfig{}, env::DefaultMapDir());
    ASSERT_TRUE(scenario.ok()) << scenario.status();
    scenario_ = *std::move(scenario);
  }
  void TearDown() override {
    if (reward_server_) reward_server_->Shutdown(DeadlineIn(std::chrono::seconds(1)));
    if (learner_server_) learner_server_->Shutdown(DeadlineIn(std::chrono::seconds(1)));
  }

  static std::string A(const std::string& name) { return *root_ + "/a/" + name; }
  static std::string B(const std::string& name) { return *root_ + "/b/" + name; }

  // The servers' side: TLS with CA a's server certificate and token.
  static TransportConfig ServerTls(bool mutual = false) {
    TransportConfig t;
    t.tls_cert = A("server.pem");
    t.tls_key = A("server.key");
    t.tls_ca = A("ca.pem");
    t.require_client_cert = mutual;
    t.token_file = A("token");
    return t;
  }
  // A client of CA a with its token and (for mutual TLS) actor-0's certificate.
  static TransportConfig ClientTls(bool with_cert = false) {
    TransportConfig t;
    t.tls_ca = A("ca.pem");
    t.tls_server_name = "localhost";
    t.token_file = A("token");
    if (with_cert) {
      t.tls_cert = A("actor-0.pem");
      t.tls_key = A("actor-0.key");
    }
    return t;
  }

  void StartReward(ServerOptions options, reward::Scorer* scorer = nullptr,
                   reward::ServiceLimits limits = {}) {
    config_.credit = "imca";
    auto made = reward::MakeScorer("count", *scenario_, config_);
    ASSERT_TRUE(made.ok()) << made.status();
    scorer_ = *std::move(made);
    reward_ = std::make_unique<reward::RewardServiceImpl>(scenario_.get(), scorer ? scorer : scorer_.get(), "count",
                                                          config_, "", limits);
    auto server = StartServer("127.0.0.1:0", {reward_.get()}, &reward_port_, options);
    ASSERT_TRUE(server.ok()) << server.status();
    reward_server_ = *std::move(server);
  }

  void StartLearner(ServerOptions options, int max_streams = learner::LearnerServiceImpl::kDefaultMaxStreams,
                    int max_actor_ids = learner::LearnerConfig{}.max_actor_ids) {
    learner::LearnerConfig config;
    config.max_actor_ids = max_actor_ids;
    config.batch_steps = 1 << 20;  // Never trains here: only queues.
    config.synchronous = false;
    config.budget_steps = 1 << 22;
    config.checkpoint_every = 0;
    config.checkpoint_seconds = 0;
    learner::MutableOptions<learner::MappoOptions>(&config).ppo.hidden = 16;
    auto learner = learner::Learner::Create(scenario_.get(), config);
    ASSERT_TRUE(learner.ok()) << learner.status();
    learner_ = *std::move(learner);
    learner_service_ = std::make_unique<learner::LearnerServiceImpl>(learner_.get(), max_streams);
    auto server = StartServer("127.0.0.1:0", {learner_service_.get()}, &learner_port_, options);
    ASSERT_TRUE(server.ok()) << server.status();
    learner_server_ = *std::move(server);
  }

  std::shared_ptr<grpc::Channel> Channel(int port, const TransportConfig& t) {
    auto channel = MakeChannel("127.0.0.1:" + std::to_string(port), t);
    EXPECT_TRUE(channel.ok()) << channel.status();
    return channel.ok() ? *channel : nullptr;
  }

  v1::ScoreRequest ScoreRequest(const std::string& actor_id = "test", int envs = 4) {
    v1::ScoreRequest request;
    *request.mutable_unroll() = testing::RandomUnroll(*scenario_, 8, envs, 11);
    request.mutable_unroll()->set_actor_id(actor_id);
    request.mutable_unroll()->set_incarnation(7);
    request.mutable_unroll()->set_sequence(++sequence_);
    return request;
  }

  grpc::Status Score(int port, const TransportConfig& t, const v1::ScoreRequest& request) {
    auto stub = v1::RewardService::NewStub(Channel(port, t));
    grpc::ClientContext context;
    context.set_deadline(DeadlineIn(std::chrono::seconds(10)));
    v1::ScoreResponse response;
    return stub->Score(&context, request, &response);
  }

  // What the reward server counted, read in-process (not over the wire).
  int64_t Scored() { return reward_->Stats().transitions_scored(); }
  int64_t Served() { return reward_->Stats().requests_served(); }

  // One PushUnrolls stream with one unroll; the call's status (OK with the
  // ack read).
  grpc::Status PushOne(int port, const TransportConfig& t, v1::PushUnrollsResponse* ack = nullptr) {
    auto stub = v1::LearnerService::NewStub(Channel(port, t));
    grpc::ClientContext context;
    context.set_deadline(DeadlineIn(std::chrono::seconds(10)));
    auto stream = stub->PushUnrolls(&context);
    v1::PushUnrollsRequest request;
    *request.mutable_unroll() = testing::RandomUnroll(*scenario_, 16, 16, 5);
    v1::PushUnrollsResponse response;
    if (stream->Write(request) && stream->Read(&response)) {
      if (ack != nullptr) *ack = response;
      stream->WritesDone();
    }
    return stream->Finish();
  }

  grpc::Status GetPolicy(int port, const TransportConfig& t) {
    auto stub = v1::LearnerService::NewStub(Channel(port, t));
    grpc::ClientContext context;
    context.set_deadline(DeadlineIn(std::chrono::seconds(10)));
    v1::Policy policy;
    return stub->GetPolicy(&context, v1::GetPolicyRequest(), &policy);
  }

  int64_t Received() { return learner_->Status().unrolls_received(); }

  int64_t sequence_ = 0;
  static std::string* root_;
  std::unique_ptr<env::Scenario> scenario_;
  reward::ScorerConfig config_;
  std::unique_ptr<reward::Scorer> scorer_;
  std::unique_ptr<reward::RewardServiceImpl> reward_;
  std::unique_ptr<grpc::Server> reward_server_;
  int reward_port_ = 0;
  std::unique_ptr<learner::Learner> learner_;
  std::unique_ptr<learner::LearnerServiceImpl> learner_service_;
  std::unique_ptr<grpc::Server> learner_server_;
  int learner_port_ = 0;
};

std::string* SecurityTest::root_ = nullptr;

ServerOptions Secured(TransportConfig t) {
  ServerOptions options;
  options.transport = std::move(t);
  return options;
}

TEST_F(SecurityTest, TlsWithTheTokenIsServedAndCounted) {
  StartReward(Secured(ServerTls()));
  StartLearner(Secured(ServerTls()));
  EXPECT_TRUE(Score(reward_port_, ClientTls(), ScoreRequest()).ok());
  EXPECT_EQ(Scored(), 32);
  v1::PushUnrollsResponse ack;
  ASSERT_TRUE(PushOne(learner_port_, ClientTls(), &ack).ok());
  EXPECT_TRUE(ack.accepted()) << ack.error();
  EXPECT_EQ(Received(), 1);
  EXPECT_TRUE(GetPolicy(learner_port_, ClientTls()).ok());
}

TEST_F(SecurityTest, NoTokenIsUnauthenticatedAndNothingIsCountedOrQueued) {
  StartReward(Secured(ServerTls()));
  StartLearner(Secured(ServerTls()));
  TransportConfig no_token = ClientTls();
  no_token.token_file.clear();
  grpc::Status status = Score(reward_port_, no_token, ScoreRequest());
  EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_THAT(status.error_message(), HasSubstr("no token"));
  EXPECT_EQ(PushOne(learner_port_, no_token).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(GetPolicy(learner_port_, no_token).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(Scored(), 0);
  EXPECT_EQ(Served(), 0);
  EXPECT_EQ(Received(), 0);
}

TEST_F(SecurityTest, AWrongTokenIsUnauthenticatedAndNothingIsCountedOrQueued) {
  StartReward(Secured(ServerTls()));
  StartLearner(Secured(ServerTls()));
  TransportConfig wrong = ClientTls();
  wrong.token_file = B("token");  // A well-formed token, not the servers'.
  grpc::Status status = Score(reward_port_, wrong, ScoreRequest());
  EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_THAT(status.error_message(), HasSubstr("token not accepted"));
  EXPECT_EQ(PushOne(learner_port_, wrong).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(Scored(), 0);
  EXPECT_EQ(Received(), 0);
}

TEST_F(SecurityTest, HealthChecksNeedNoToken) {
  StartReward(Secured(ServerTls()));
  TransportConfig no_token = ClientTls();
  no_token.token_file.clear();
  const absl::StatusOr<bool> serving = CheckHealth(Channel(reward_port_, no_token), std::chrono::seconds(10));
  ASSERT_TRUE(serving.ok()) << serving.status();
  EXPECT_TRUE(*serving);
  // The same channel without a token is refused any other call.
  EXPECT_EQ(Score(reward_port_, no_token, ScoreRequest()).error_code(), grpc::StatusCode::UNAUTHENTICATED);
}

TEST_F(SecurityTest, APlaintextClientIsUnavailableAndReadsAsATlsFailure) {
  StartReward(Secured(ServerTls()));
  StartLearner(Secured(ServerTls()));
  auto stub = v1::RewardService::NewStub(MakeChannel("127.0.0.1:" + std::to_string(reward_port_)));
  grpc::ClientContext context;
  context.set_deadline(DeadlineIn(std::chrono::seconds(5)));
  v1::ScoreResponse response;
  const grpc::Status status = stub->Score(&context, ScoreRequest(), &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_TRUE(LooksLikeTlsFailure(FromGrpcStatus(status))) << status.error_message();
  EXPECT_THAT(DescribeRpcFailure("reward server", FromGrpcStatus(status), /*tls=*/false),
              HasSubstr("if the server runs TLS, this client needs --tls_ca"));
  EXPECT_EQ(PushOne(learner_port_, TransportConfig{}).error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_EQ(Scored(), 0);
  EXPECT_EQ(Received(), 0);
}

TEST_F(SecurityTest, AServerCertificateOfAnotherCaIsUnavailableAndSaysHandshake) {
  StartReward(Secured(ServerTls()));
  TransportConfig other = ClientTls();
  other.tls_ca = B("ca.pem");  // Trusts CA b; the server's certificate is CA a's.
  const grpc::Status status = Score(reward_port_, other, ScoreRequest());
  EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_TRUE(LooksLikeTlsFailure(FromGrpcStatus(status))) << status.error_message();
  EXPECT_THAT(DescribeRpcFailure("reward server", FromGrpcStatus(status), true), HasSubstr("TLS handshake"));
  EXPECT_EQ(Scored(), 0);
}

TEST_F(SecurityTest, MutualTlsRefusesAClientWithoutOrWithAForeignCertificate) {
  StartReward(Secured(ServerTls(/*mutual=*/true)));
  StartLearner(Secured(ServerTls(/*mutual=*/true)));
  // No client certificate: the server closes the handshake (UNAVAILABLE, not 16).
  EXPECT_EQ(Score(reward_port_, ClientTls(), ScoreRequest()).error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_EQ(PushOne(learner_port_, ClientTls()).error_code(), grpc::StatusCode::UNAVAILABLE);
  TransportConfig foreign = ClientTls();
  foreign.tls_cert = B("actor-0.pem");  // Signed by CA b.
  foreign.tls_key = B("actor-0.key");
  const grpc::Status status = Score(reward_port_, foreign, ScoreRequest());
  EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_TRUE(LooksLikeTlsFailure(FromGrpcStatus(status))) << status.error_message();
  EXPECT_EQ(Scored(), 0);
  EXPECT_EQ(Received(), 0);
  // With actor-0's certificate of CA a: served, and the identity is logged.
  ::testing::internal::CaptureStderr();
  EXPECT_TRUE(Score(reward_port_, ClientTls(/*with_cert=*/true), ScoreRequest("actor-zero")).ok());
  EXPECT_TRUE(PushOne(learner_port_, ClientTls(/*with_cert=*/true)).ok());
  const std::string log = ::testing::internal::GetCapturedStderr();
  EXPECT_THAT(log, HasSubstr("first Score from actor-zero (certificate CN=actor-0"));
  EXPECT_THAT(log, HasSubstr("unroll stream from test (certificate CN=actor-0"));
  EXPECT_EQ(Scored(), 32);
  EXPECT_EQ(Received(), 1);
}

TEST_F(SecurityTest, AnOversizedRequestIsResourceExhaustedBeforeAnyHandler) {
  ServerOptions small = Secured(ServerTls());
  small.max_receive_bytes = 1 << 20;
  StartReward(small);
  StartLearner(small);
  v1::ScoreRequest big = ScoreRequest("test", 2048);  // 8 x 2048 transitions: over 1 MiB.
  ASSERT_GT(big.ByteSizeLong(), size_t{1} << 20);
  const grpc::Status status = Score(reward_port_, ClientTls(), big);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << status.error_message();
  EXPECT_EQ(Scored(), 0);
  EXPECT_EQ(reward_->Stats().requests_rejected(), 0);  // No handler ran.

  auto stub = v1::LearnerService::NewStub(Channel(learner_port_, ClientTls()));
  grpc::ClientContext context;
  context.set_deadline(DeadlineIn(std::chrono::seconds(10)));
  auto stream = stub->PushUnrolls(&context);
  v1::PushUnrollsRequest request;
  *request.mutable_unroll() = testing::RandomUnroll(*scenario_, 64, 256, 3);
  ASSERT_GT(request.ByteSizeLong(), size_t{1} << 20);
  v1::PushUnrollsResponse ack;
  if (stream->Write(request)) {
    EXPECT_FALSE(stream->Read(&ack));
  }
  EXPECT_EQ(stream->Finish().error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_EQ(Received(), 0);
  // The same server still serves a request under the cap.
  EXPECT_TRUE(Score(reward_port_, ClientTls(), ScoreRequest()).ok());
  EXPECT_EQ(Scored(), 32);
}

TEST_F(SecurityTest, TheLearnerServesAtMostMaxStreamsStreams) {
  StartLearner(Secured(ServerTls()), /*max_streams=*/2);
  auto stub = v1::LearnerService::NewStub(Channel(learner_port_, ClientTls()));
  struct Open {
    grpc::ClientContext context;
    std::unique_ptr<grpc::ClientReaderWriter<v1::PushUnrollsRequest, v1::PushUnrollsResponse>> stream;
  };
  std::vector<std::unique_ptr<Open>> open;
  for (int i = 0; i < 2; ++i) {
    open.push_back(std::make_unique<Open>());
    open.back()->context.set_deadline(DeadlineIn(std::chrono::seconds(30)));
    open.back()->stream = stub->PushUnrolls(&open.back()->context);
    v1::PushUnrollsRequest request;
    *request.mutable_unroll() = testing::RandomUnroll(*scenario_, 16, 16, 20 + i);
    request.mutable_unroll()->set_actor_id("held-" + std::to_string(i));
    v1::PushUnrollsResponse ack;
    ASSERT_TRUE(open.back()->stream->Write(request) && open.back()->stream->Read(&ack));
  }
  const grpc::Status third = PushOne(learner_port_, ClientTls());
  EXPECT_EQ(third.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(third.error_message(), HasSubstr("--max_streams"));
  EXPECT_EQ(Received(), 2);
  open.front()->stream->WritesDone();
  EXPECT_TRUE(open.front()->stream->Finish().ok());
  open.erase(open.begin());
  // A slot is free again (the handler returns just after Finish: retry briefly).
  grpc::Status again;
  for (int attempt = 0; attempt < 50; ++attempt) {
    again = PushOne(learner_port_, ClientTls());
    if (again.error_code() != grpc::StatusCode::RESOURCE_EXHAUSTED) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_TRUE(again.ok()) << again.error_message();
  EXPECT_EQ(Received(), 3);
  for (auto& o : open) {
    o->stream->WritesDone();
    o->stream->Finish();
  }
}

TEST_F(SecurityTest, TheLearnerHoldsAtMostMaxStreamsWaitingPolicyCalls) {
  StartLearner(Secured(ServerTls()), /*max_streams=*/1);
  auto stub = v1::LearnerService::NewStub(Channel(learner_port_, ClientTls()));
  auto wait_for = [&](int64_t version, int wait_ms) {
    grpc::ClientContext context;
    context.set_deadline(DeadlineIn(std::chrono::seconds(10)));
    v1::GetPolicyRequest request;
    request.set_min_version(version);
    request.set_wait_ms(wait_ms);
    v1::Policy policy;
    return stub->GetPolicy(&context, request, &policy);
  };
  // One call waits 1.5 s (for a version that never comes; it retries while
  // a probe below holds the slot for its 1 ms) ...
  std::thread waiting([&] {
    grpc::Status status;
    do {
      status = wait_for(5, 1500);
    } while (status.error_code() == grpc::StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_TRUE(status.ok()) << status.error_message();
  });
  grpc::Status second;
  for (int attempt = 0; attempt < 100; ++attempt) {  // Until the first holds its slot.
    second = wait_for(5, 1);
    if (second.error_code() == grpc::StatusCode::RESOURCE_EXHAUSTED) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  // ... so a second waiting call is refused, while one that does not wait is served.
  EXPECT_EQ(second.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(second.error_message(), HasSubstr("waiting GetPolicy calls"));
  EXPECT_TRUE(wait_for(0, 0).ok());
  waiting.join();
}

// Holds every Score inside the scorer until released.
class HeldScorer final : public testing::ForwardingScorer {
 public:
  using ForwardingScorer::ForwardingScorer;
  absl::Status Score(const reward::TransitionBatch& batch, bool dry_run, const reward::ScoreOutput& out) override {
    {
      absl::MutexLock lock(&mu_);
      ++entered_;
      mu_.Await(absl::Condition(&released_));
    }
    return ForwardingScorer::Score(batch, dry_run, out);
  }

  bool AwaitEntered(int n) {
    absl::MutexLock lock(&mu_);
    auto reached = [this, n]() ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_) { return entered_ >= n; };
    return mu_.AwaitWithTimeout(absl::Condition(&reached), absl::Seconds(20));
  }
  void Release() {
    absl::MutexLock lock(&mu_);
    released_ = true;
  }

 private:
  absl::Mutex mu_;
  int entered_ ABSL_GUARDED_BY(mu_) = 0;
  bool released_ ABSL_GUARDED_BY(mu_) = false;
};

TEST_F(SecurityTest, AFloodingClientTakesOnlyItsOwnSlots) {
  reward::ServiceLimits limits;
  limits.max_inflight = 3;
  limits.max_inflight_per_actor = 2;
  config_.credit = "imca";
  auto real = reward::MakeScorer("count", *scenario_, config_);
  ASSERT_TRUE(real.ok());
  HeldScorer held(real->get());
  StartReward(Secured(ServerTls()), &held, limits);
  std::vector<std::thread> calls;
  std::vector<grpc::Status> results(3);
  // Requests made here, not on the calling threads; incarnation 0 (not
  // tracked for retries), so the order the held calls finish in cannot make
  // one of them a "repeat".
  auto call = [&](int i, std::string id) {
    v1::ScoreRequest request = ScoreRequest(id);
    request.mutable_unroll()->set_incarnation(0);
    calls.emplace_back([&, i, request] { results[i] = Score(reward_port_, ClientTls(), request); });
  };
  call(0, "flood");
  call(1, "flood");
  ASSERT_TRUE(held.AwaitEntered(2));
  // The flooder's third call is refused at once; another actor is served.
  grpc::Status third = Score(reward_port_, ClientTls(), ScoreRequest("flood"));
  EXPECT_EQ(third.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(third.error_message(), HasSubstr("of this client"));
  call(2, "honest");
  ASSERT_TRUE(held.AwaitEntered(3));
  // All slots held: the total bound refuses anyone.
  grpc::Status full = Score(reward_port_, ClientTls(), ScoreRequest("late"));
  EXPECT_EQ(full.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(full.error_message(), HasSubstr("in total"));
  held.Release();
  for (std::thread& t : calls) t.join();
  for (const grpc::Status& s : results) EXPECT_TRUE(s.ok()) << s.error_message();
  // The three served requests, 32 transitions each.
  EXPECT_EQ(Scored(), 3 * 32);
  EXPECT_EQ(reward_->Stats().requests_rejected(), 2);
}

TEST_F(SecurityTest, AnActorWithAWrongTokenStopsAtOnceWithOneLine) {
  StartReward(Secured(ServerTls()));
  StartLearner(Secured(ServerTls()));
  TransportConfig wrong = ClientTls();
  wrong.token_file = B("token");
  actor::ActorConfig config;
  config.actor_id = "actor-x";
  config.num_envs = 4;
  config.unroll_length = 8;
  config.tls = true;
  actor::Actor actor(scenario_.get(), config, Channel(learner_port_, wrong), Channel(reward_port_, wrong));
  const auto start = std::chrono::steady_clock::now();
  const absl::Status status = actor.Run();
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(5));
  EXPECT_TRUE(absl::IsUnauthenticated(status)) << status;
  EXPECT_THAT(status.message(), HasSubstr("learner refused this client's credentials"));
  EXPECT_EQ(Received(), 0);
  EXPECT_EQ(Scored(), 0);
}

TEST_F(SecurityTest, InventedActorIdsCannotGrowTheLearnersOrTheRewardServersBookkeeping) {
  StartLearner(Secured(ServerTls()), learner::LearnerServiceImpl::kDefaultMaxStreams, /*max_actor_ids=*/2);
  auto push = [&](const std::string& id, int64_t sequence) {
    v1::Unroll u = testing::RandomUnroll(*scenario_, 16, 4, 40 + sequence);
    u.set_actor_id(id);
    u.set_incarnation(9);
    u.set_sequence(sequence);
    return learner_->Push(std::move(u));
  };
  EXPECT_TRUE(learner::Accepted(push("a", 1)));
  EXPECT_TRUE(learner::Accepted(push("b", 1)));
  const absl::StatusOr<learner::PushOutcome> third = push("c", 1);
  EXPECT_EQ(learner::RejectionOf(third), v1::REJECTION_OVER_CAP) << learner::Why(third);
  EXPECT_THAT(learner::Why(third), HasSubstr("at most 2 actor ids"));
  EXPECT_TRUE(learner::Accepted(push("a", 2)));  // Known ids go on.
  EXPECT_EQ(Received(), 3);

  reward::ServiceLimits limits;
  limits.max_tracked_actors = 1;
  StartReward(Secured(ServerTls()), nullptr, limits);
  v1::ScoreRequest first = ScoreRequest("first"), other = ScoreRequest("other");
  ASSERT_TRUE(Score(reward_port_, ClientTls(), first).ok());
  ASSERT_TRUE(Score(reward_port_, ClientTls(), other).ok());
  // The tracked id's retry is answered without counting; the id past the
  // cap is not remembered, so its retry counts again (the documented cost).
  ASSERT_TRUE(Score(reward_port_, ClientTls(), first).ok());
  ASSERT_TRUE(Score(reward_port_, ClientTls(), other).ok());
  EXPECT_EQ(reward_->Stats().requests_repeated(), 1);
  EXPECT_EQ(Scored(), 3 * 32);
}

TEST(TransportConfigTest, BadCombinationsNameTheFlag) {
  TransportConfig t;
  t.tls_cert = "x.pem";
  EXPECT_THAT(ValidateServerTransport(t).message(), HasSubstr("--tls_key"));
  t = {};
  t.token_file = "token";
  EXPECT_THAT(ValidateServerTransport(t).message(), HasSubstr("--token_file needs --tls_cert"));
  EXPECT_THAT(ValidateClientTransport(t).message(), HasSubstr("need --tls_ca"));
  t = {};
  t.tls_ca = "ca.pem";  // A server with a CA but no certificate would serve plaintext.
  EXPECT_THAT(ValidateServerTransport(t).message(), HasSubstr("--tls_ca on a server needs --tls_cert"));
  t = {};
  t.tls_cert = "a";
  t.tls_key = "b";
  t.require_client_cert = true;
  EXPECT_THAT(ValidateServerTransport(t).message(), HasSubstr("--tls_client_auth needs"));
  t.tls_ca = "/nonexistent/ca.pem";
  int port = 0;
  ServerOptions options;
  options.transport = t;
  auto server = StartServer("127.0.0.1:0", {}, &port, options);
  ASSERT_FALSE(server.ok());
  EXPECT_TRUE(absl::IsInvalidArgument(server.status()));
  EXPECT_THAT(server.status().message(), HasSubstr("--tls_cert: cannot read PEM file 'a'"));
}

TEST(TokenFileTest, RejectsBadTokensNamingTheLineAndReloadsOnChange) {
  const std::string path = ::testing::TempDir() + "/token_test_" + std::to_string(getpid());
  WriteFile(path, "");
  EXPECT_THAT(TokenFile::Open(path).status().message(), HasSubstr("holds no token"));
  WriteFile(path, "0123456789abcdef0123\nshort\n");
  EXPECT_THAT(TokenFile::Open(path).status().message(), HasSubstr("line 2"));
  WriteFile(path, "with space in the token itself\n");
  EXPECT_FALSE(TokenFile::Open(path).ok());
  EXPECT_THAT(TokenFile::Open(path + ".missing").status().message(), HasSubstr("--token_file: cannot read"));
  // Rotation: old and new accepted together, then the old one removed.
  WriteFile(path, "old-token-0123456789\n  new-token-0123456789  \n\n");
  auto tokens = TokenFile::Open(path);
  ASSERT_TRUE(tokens.ok()) << tokens.status();
  EXPECT_EQ((*tokens)->First(), "old-token-0123456789");
  EXPECT_TRUE((*tokens)->Accepts("old-token-0123456789"));
  EXPECT_TRUE((*tokens)->Accepts("new-token-0123456789"));
  EXPECT_FALSE((*tokens)->Accepts("new-token-012345678"));
  EXPECT_FALSE((*tokens)->Accepts(""));
  WriteFile(path, "new-token-0123456789\n");
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));
  EXPECT_FALSE((*tokens)->Accepts("old-token-0123456789"));
  EXPECT_EQ((*tokens)->First(), "new-token-0123456789");
  // A file turned invalid keeps the last good tokens.
  WriteFile(path, "bad\n");
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));
  EXPECT_TRUE((*tokens)->Accepts("new-token-0123456789"));
  fs::remove(path);
}

}  // namespace
}  // namespace imca
