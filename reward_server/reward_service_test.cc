// RewardService over a real loopback gRPC channel: every bad field gives
// INVALID_ARGUMENT naming it, and a rejected request changes no count.
#include <unistd.h>

#include <filesystem>
#include <functional>
#include <memory>
#include <string>

#include <grpcpp/generic/generic_stub.h>

#include "common/env/env.h"
#include "common/protocol/test_unrolls.h"
#include "common/rpc/grpc_util.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "imca/v1/reward_service.grpc.pb.h"
#include "reward_server/make_scorer.h"
#include "reward_server/reward_service.h"

namespace imca::reward {
namespace {

using ::testing::HasSubstr;

class RewardServiceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    auto scenario = env::MakeScenario(env::ScenarioConfig{}, env::DefaultMapDir());
    ASSERT_TRUE(scenario.ok()) << scenario.status();
    scenario_ = *std::move(scenario);
    config_.credit = "imca";
    auto scorer = MakeScorer("count", *scenario_, config_);
    ASSERT_TRUE(scorer.ok()) << scorer.status();
    scorer_ = *std::move(scorer);
    service_ = std::make_unique<RewardServiceImpl>(scenario_.get(), scorer_.get(), "count", config_,
                                                   snapshot_);
    auto server = StartServer("127.0.0.1:0", {service_.get()}, &port_);
    ASSERT_TRUE(server.ok()) << server.status();
    server_ = *std::move(server);
    stub_ = v1::RewardService::NewStub(MakeChannel("127.0.0.1:" + std::to_string(port_)));
  }
  void TearDown() override { server_->Shutdown(); }

  grpc::Status Score(const v1::ScoreRequest& request, v1::ScoreResponse* response) {
    grpc::ClientContext context;
    context.set_deadline(DeadlineIn(std::chrono::seconds(10)));
    return stub_->Score(&context, request, response);
  }

  v1::RewardStats Stats() {
    grpc::ClientContext context;
    v1::RewardStats stats;
    EXPECT_TRUE(stub_->GetStats(&context, v1::GetStatsRequest(), &stats).ok());
    return stats;
  }

  v1::ScoreRequest Valid() {
    v1::ScoreRequest request;
    *request.mutable_unroll() = testing::RandomUnroll(*scenario_, 8, 4, 11);
    return request;
  }

  std::unique_ptr<env::Scenario> scenario_;
  ScorerConfig config_;
  std::string snapshot_;
  std::unique_ptr<CreditScorer> scorer_;
  std::unique_ptr<RewardServiceImpl> service_;
  int port_ = 0;
  std::unique_ptr<grpc::Server> server_;
  std::unique_ptr<v1::RewardService::Stub> stub_;
};

TEST_F(RewardServiceTest, ScoresAValidUnroll) {
  v1::ScoreResponse response;
  ASSERT_TRUE(Score(Valid(), &response).ok());
  EXPECT_EQ(response.num_transitions(), 32);
  EXPECT_EQ(response.agent_rewards_size(), 64);
  EXPECT_EQ(response.shares_size(), 64);
  for (int i = 0; i < 32; ++i) {
    EXPECT_GT(response.global_rewards(i), 0.0f);
    EXPECT_NEAR(response.shares(2 * i) + response.shares(2 * i + 1), 1.0f, 1e-5);
    EXPECT_NEAR(response.agent_rewards(2 * i) + response.agent_rewards(2 * i + 1),
                response.global_rewards(i), 1e-5);
  }
  const v1::RewardStats stats = Stats();
  EXPECT_EQ(stats.transitions_scored(), 32);
  EXPECT_GT(stats.distinct_keys(), 0);
  EXPECT_EQ(stats.credit(), "imca");
}

TEST_F(RewardServiceTest, DryRunLeavesCountsAlone) {
  v1::ScoreRequest request = Valid();
  request.set_dry_run(true);
  v1::ScoreResponse response;
  ASSERT_TRUE(Score(request, &response).ok());
  EXPECT_EQ(Stats().distinct_keys(), 0);
}

struct BadCase {
  const char* name;
  std::function<void(v1::Unroll*)> corrupt;
  const char* field;
};

TEST_F(RewardServiceTest, EveryBadFieldIsInvalidArgumentAndChangesNothing) {
  const BadCase cases[] = {
      {"scenario", [](v1::Unroll* u) { u->set_scenario("chess"); }, "unroll.scenario"},
      {"other map", [](v1::Unroll* u) { u->set_scenario_fingerprint(u->scenario_fingerprint() ^ 1); },
       "unroll.scenario_fingerprint"},
      {"agents", [](v1::Unroll* u) { u->set_num_agents(3); }, "unroll.num_agents"},
      {"actions count", [](v1::Unroll* u) { u->set_num_actions(4); }, "unroll.num_actions"},
      {"state size", [](v1::Unroll* u) { u->set_state_size(5); }, "unroll.state_size"},
      {"length", [](v1::Unroll* u) { u->set_length(0); }, "unroll.length"},
      {"envs", [](v1::Unroll* u) { u->set_num_envs(-1); }, "unroll.num_envs"},
      {"too big", [](v1::Unroll* u) { u->set_length(100000); }, "exceeds the limit"},
      {"states size", [](v1::Unroll* u) { u->mutable_states()->RemoveLast(); }, "unroll.states"},
      {"action range", [](v1::Unroll* u) { u->set_actions(5, 7); }, "unroll.actions[5]"},
      {"negative action", [](v1::Unroll* u) { u->set_actions(0, -1); }, "unroll.actions[0]"},
      {"cell on wall", [](v1::Unroll* u) { u->set_states(4 * 3 + 1, 0); }, "unroll.states[3]"},
      {"cell off map", [](v1::Unroll* u) { u->set_next_states(2, 100000); }, "unroll.next_states[0]"},
      {"nan prob", [](v1::Unroll* u) { u->set_action_probs(3, std::nanf("")); }, "unroll.action_probs[3]"},
      {"row sum", [](v1::Unroll* u) { u->set_action_probs(0, 0.5f); }, "unroll.action_probs row 0"},
      {"episode ids", [](v1::Unroll* u) { u->clear_episode_ids(); }, "unroll.episode_ids"},
  };
  for (const BadCase& bad : cases) {
    v1::ScoreRequest request = Valid();
    bad.corrupt(request.mutable_unroll());
    v1::ScoreResponse response;
    const grpc::Status status = Score(request, &response);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << bad.name;
    EXPECT_THAT(status.error_message(), HasSubstr(bad.field)) << bad.name;
  }
  v1::ScoreResponse response;
  EXPECT_EQ(Score(v1::ScoreRequest(), &response).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  const v1::RewardStats stats = Stats();
  EXPECT_EQ(stats.distinct_keys(), 0);
  EXPECT_EQ(stats.transitions_scored(), 0);
  EXPECT_EQ(stats.requests_rejected(), static_cast<int64_t>(std::size(cases)) + 1);
}

// One request message, one response message over any method, as grpc_cli
// does it: the serialized bytes go over a generic stream.
grpc::Status CallRaw(const std::shared_ptr<grpc::Channel>& channel, const std::string& method,
                     const std::string& request, std::string* response) {
  grpc::GenericStub stub(channel);
  grpc::CompletionQueue cq;
  grpc::ClientContext context;
  context.set_deadline(DeadlineIn(std::chrono::seconds(10)));
  auto call = stub.PrepareCall(&context, method, &cq);
  void* tag;
  bool ok;
  call->StartCall(reinterpret_cast<void*>(1));
  cq.Next(&tag, &ok);
  grpc::Slice slice(request);
  grpc::ByteBuffer out(&slice, 1);
  call->Write(out, reinterpret_cast<void*>(2));
  cq.Next(&tag, &ok);
  call->WritesDone(reinterpret_cast<void*>(3));
  cq.Next(&tag, &ok);
  grpc::ByteBuffer in;
  call->Read(&in, reinterpret_cast<void*>(4));
  cq.Next(&tag, &ok);
  if (ok) {
    std::vector<grpc::Slice> slices;
    in.Dump(&slices).ok();
    for (const grpc::Slice& s : slices) response->append(reinterpret_cast<const char*>(s.begin()), s.size());
  }
  grpc::Status status;
  call->Finish(&status, reinterpret_cast<void*>(5));
  cq.Next(&tag, &ok);
  cq.Shutdown();
  while (cq.Next(&tag, &ok)) {
  }
  return status;
}

TEST_F(RewardServiceTest, ServesHealthCheckingAndReflection) {
  auto channel = MakeChannel("127.0.0.1:" + std::to_string(port_));
  std::string response;
  // grpc.health.v1.HealthCheckRequest{service: ""} is empty; SERVING is
  // HealthCheckResponse{status: 1} = bytes 08 01.
  ASSERT_TRUE(CallRaw(channel, "/grpc.health.v1.Health/Check", "", &response).ok());
  EXPECT_EQ(response, std::string("\x08\x01", 2));
  // ServerReflectionRequest{list_services: ""} = field 7, empty string.
  response.clear();
  ASSERT_TRUE(CallRaw(channel, "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo",
                      std::string("\x3a\x00", 2), &response)
                  .ok());
  EXPECT_THAT(response, HasSubstr("imca.v1.RewardService"));
}

TEST_F(RewardServiceTest, ARetriedScoreIsAnsweredButCountedOnce) {
  v1::ScoreRequest request = Valid();
  request.mutable_unroll()->set_actor_id("actor-3");
  request.mutable_unroll()->set_incarnation(42);
  request.mutable_unroll()->set_sequence(1);
  v1::ScoreResponse first, again;
  ASSERT_TRUE(Score(request, &first).ok());
  const int64_t keys = Stats().distinct_keys();
  // The same unroll again (its first answer was lost): answered, not counted.
  ASSERT_TRUE(Score(request, &again).ok());
  EXPECT_EQ(again.num_transitions(), first.num_transitions());
  v1::RewardStats stats = Stats();
  EXPECT_EQ(stats.transitions_scored(), 32);
  EXPECT_EQ(stats.requests_repeated(), 1);
  EXPECT_EQ(stats.distinct_keys(), keys);
  // The next sequence, or the same one from a new incarnation, counts.
  request.mutable_unroll()->set_sequence(2);
  ASSERT_TRUE(Score(request, &again).ok());
  request.mutable_unroll()->set_incarnation(43);
  request.mutable_unroll()->set_sequence(1);
  ASSERT_TRUE(Score(request, &again).ok());
  stats = Stats();
  EXPECT_EQ(stats.transitions_scored(), 3 * 32);
  EXPECT_EQ(stats.requests_repeated(), 1);
}

TEST_F(RewardServiceTest, SnapshotWithoutPathIsFailedPrecondition) {
  grpc::ClientContext context;
  v1::SnapshotResponse response;
  EXPECT_EQ(stub_->Snapshot(&context, v1::SnapshotRequest(), &response).error_code(),
            grpc::StatusCode::FAILED_PRECONDITION);
}

TEST_F(RewardServiceTest, StoppedServiceIsUnavailable) {
  service_->StopAccepting();
  v1::ScoreResponse response;
  EXPECT_EQ(Score(Valid(), &response).error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_EQ(service_->Stats().requests_rejected(), 1);  // Refused, and counted as such.
  EXPECT_EQ(service_->Stats().requests_served(), 0);
  EXPECT_THAT(service_->metrics().Text(), HasSubstr("\nimca_reward_requests_rejected_total 1\n"));
}


// EITI and EDTI over loopback on EDTI's pass: the influence matrix travels in
// the response for edti only, and both refuse joint credit modes at creation.
TEST(InfluenceServiceTest, EdtiReturnsInfluencesEitiDoesNot) {
  env::ScenarioConfig pass;
  pass.name = "pass";
  auto scenario = env::MakeScenario(pass, env::DefaultMapDir());
  ASSERT_TRUE(scenario.ok()) << scenario.status();
  const int n = (*scenario)->num_agents();
  for (const std::string kind : {"eiti", "edti"}) {
    ScorerConfig config;
    config.credit = "independent";
    auto scorer = MakeScorer(kind, **scenario, config);
    ASSERT_TRUE(scorer.ok()) << scorer.status();
    RewardServiceImpl service(scenario->get(), scorer->get(), kind, config, "");
    int port = 0;
    auto server = StartServer("127.0.0.1:0", {&service}, &port);
    ASSERT_TRUE(server.ok()) << server.status();
    auto stub = v1::RewardService::NewStub(MakeChannel("127.0.0.1:" + std::to_string(port)));
    v1::ScoreRequest request;
    *request.mutable_unroll() = testing::RandomUnroll(**scenario, 16, 4, 5);
    v1::ScoreResponse response;
    grpc::ClientContext context;
    context.set_deadline(DeadlineIn(std::chrono::seconds(10)));
    ASSERT_TRUE(stub->Score(&context, request, &response).ok()) << kind;
    const int N = response.num_transitions();
    ASSERT_EQ(N, 64);
    for (int i = 0; i < N * n; ++i) EXPECT_GT(response.agent_rewards(i), 0.0f) << kind << " curiosity > 0";
    if (kind == "eiti") {
      EXPECT_EQ(response.influences_size(), 0);
    } else {
      ASSERT_EQ(response.influences_size(), N * n * n);
      for (int t = 0; t < N; ++t) {
        for (int a = 0; a < n; ++a) EXPECT_EQ(response.influences((t * n + a) * n + a), 0.0f);
      }
    }
    grpc::ClientContext stats_context;
    v1::RewardStats stats;
    ASSERT_TRUE(stub->GetStats(&stats_context, v1::GetStatsRequest(), &stats).ok());
    EXPECT_EQ(stats.reward_kind(), kind);
    EXPECT_GT(stats.distinct_keys(), 0) << "the influence tables";
    EXPECT_GT(stats.distinct_local_keys(), 0) << "the curiosity's cell counts";
    (*server)->Shutdown();
  }
}

// The answered calls' time by phase (docs/metrics.md): a learned kind
// reports its encode and train parts and, under imca, its counterfactual
// rows; a count kind's whole call is novelty; no call has a counterfactual
// part without imca; and the phases never add up to more than the handler.
TEST(ScoreTimelineTest, PhasesAreReportedByWhatRanAndFitInTheHandler) {
  auto scenario = env::MakeScenario(env::ScenarioConfig{}, env::DefaultMapDir());
  ASSERT_TRUE(scenario.ok()) << scenario.status();
  struct Run {
    std::string kind;
    std::string credit;
  };
  for (const Run& run : {Run{"rnd", "imca"}, Run{"rnd", "shared"}, Run{"count", "imca"}}) {
    const std::string label = run.kind + " " + run.credit;
    ScorerConfig config;
    config.credit = run.credit;
    auto scorer = MakeScorer(run.kind, **scenario, config);
    ASSERT_TRUE(scorer.ok()) << scorer.status();
    RewardServiceImpl service(scenario->get(), scorer->get(), run.kind, config, "");
    int port = 0;
    auto server = StartServer("127.0.0.1:0", {&service}, &port);
    ASSERT_TRUE(server.ok()) << server.status();
    auto stub = v1::RewardService::NewStub(MakeChannel("127.0.0.1:" + std::to_string(port)));
    for (int call = 0; call < 3; ++call) {
      v1::ScoreRequest request;
      *request.mutable_unroll() = testing::RandomUnroll(**scenario, 32, 8, 20 + call);
      v1::ScoreResponse response;
      grpc::ClientContext context;
      context.set_deadline(DeadlineIn(std::chrono::seconds(30)));
      ASSERT_TRUE(stub->Score(&context, request, &response).ok()) << label;
    }
    const v1::RewardStats stats = service.Stats();
    const auto& seconds = stats.score_seconds();
    ASSERT_EQ(seconds.size(), kNumScorePhases) << label;
    double sum = 0;
    for (int p = 0; p < kNumScorePhases; ++p) {
      const std::string phase = ScorePhaseName(static_cast<ScorePhase>(p));
      ASSERT_TRUE(seconds.contains(phase)) << label << " " << phase;
      EXPECT_GE(seconds.at(phase), 0.0) << label << " " << phase;
      sum += seconds.at(phase);
    }
    EXPECT_GT(seconds.at("novelty"), 0.0) << label;
    EXPECT_GT(stats.handler_seconds(), 0.0) << label;
    EXPECT_LE(sum, stats.handler_seconds()) << label;
    if (run.kind == "rnd") {
      EXPECT_GT(seconds.at("encode"), 0.0) << label;
      EXPECT_GT(seconds.at("train"), 0.0) << label;
    } else {
      EXPECT_EQ(seconds.at("encode"), 0.0) << label << ": a count kind reports no parts";
      EXPECT_EQ(seconds.at("train"), 0.0) << label;
    }
    if (run.kind == "rnd" && run.credit == "imca") {
      EXPECT_GT(seconds.at("counterfactual"), 0.0) << label;
    } else {
      EXPECT_EQ(seconds.at("counterfactual"), 0.0) << label;
    }
    (*server)->Shutdown();
  }
}

// A server that dies without its final snapshot (the scorer is dropped, as
// by kill -9: the journal's writes are all it leaves) comes back with every
// answered Score counted, for each kind with count tables.
TEST(RecoveryTest, EveryAnsweredScoreSurvivesAServerThatDies) {
  const std::string dir = ::testing::TempDir() + "/recovery_test_" + std::to_string(getpid());
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  for (const std::string kind : {"count", "eiti"}) {
    env::ScenarioConfig scenario_config;
    scenario_config.name = kind == "count" ? "coop_nav" : "pass";
    auto scenario = env::MakeScenario(scenario_config, env::DefaultMapDir());
    ASSERT_TRUE(scenario.ok()) << scenario.status();
    ScorerConfig config;
    config.credit = kind == "count" ? "imca" : "independent";
    const std::string snapshot = dir + "/" + kind + ".bin";
    // One incarnation of the server: restore, serve `requests` Score calls
    // (a Snapshot RPC after the second), return the stats it answered with.
    auto serve = [&](int requests, uint64_t seed) {
      auto scorer = MakeScorer(kind, **scenario, config);
      EXPECT_TRUE(scorer.ok()) << scorer.status();
      EXPECT_TRUE((*scorer)->Restore(snapshot, /*sync=*/false).ok());
      RewardServiceImpl service(scenario->get(), scorer->get(), kind, config, snapshot);
      int port = 0;
      auto server = StartServer("127.0.0.1:0", {&service}, &port);
      EXPECT_TRUE(server.ok()) << server.status();
      auto stub = v1::RewardService::NewStub(MakeChannel("127.0.0.1:" + std::to_string(port)));
      for (int r = 0; r < requests; ++r) {
        v1::ScoreRequest request;
        *request.mutable_unroll() = testing::RandomUnroll(**scenario, 8, 4, seed + r);
        v1::ScoreResponse response;
        grpc::ClientContext context;
        context.set_deadline(DeadlineIn(std::chrono::seconds(10)));
        EXPECT_TRUE(stub->Score(&context, request, &response).ok()) << kind;
        if (r == 1) {
          grpc::ClientContext snapshot_context;
          v1::SnapshotResponse saved;
          EXPECT_TRUE(stub->Snapshot(&snapshot_context, v1::SnapshotRequest(), &saved).ok());
        }
      }
      grpc::ClientContext stats_context;
      v1::RewardStats stats;
      EXPECT_TRUE(stub->GetStats(&stats_context, v1::GetStatsRequest(), &stats).ok());
      (*server)->Shutdown();
      return stats;  // No final Save: the scorer goes as a killed process's would.
    };
    const v1::RewardStats first = serve(5, 100);
    EXPECT_EQ(first.transitions_scored(), 5 * 32) << kind;
    const v1::RewardStats second = serve(0, 0);
    EXPECT_EQ(second.transitions_scored(), first.transitions_scored()) << kind;
    EXPECT_EQ(second.distinct_keys(), first.distinct_keys()) << kind;
    EXPECT_EQ(second.distinct_local_keys(), first.distinct_local_keys()) << kind;
    const v1::RewardStats third = serve(3, 200);  // Goes on counting from there.
    EXPECT_EQ(third.transitions_scored(), 8 * 32) << kind;
    EXPECT_EQ(serve(0, 0).distinct_keys(), third.distinct_keys()) << kind;
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace imca::reward
