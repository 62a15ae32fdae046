// gRPC calls counted and timed on both sides of a real loopback connection:
// by method and status code, unknown methods as "other", one latency
// observation per completed call (common/rpc/rpc_metrics.h).
#include "common/rpc/rpc_metrics.h"

#include <chrono>
#include <memory>
#include <string>
#include <thread>

#include <grpcpp/grpcpp.h>

#include "absl/strings/str_cat.h"
#include "common/env/env.h"
#include "common/metrics/metrics_testing.h"
#include "common/rpc/grpc_util.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "imca/v1/learner_service.grpc.pb.h"
#include "learner/algorithms/mappo/mappo_options.h"
#include "learner/learner.h"
#include "learner/learner_service.h"

namespace imca {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

using metrics::testing::SampleValue;

grpc::Status GenericCall(const std::shared_ptr<grpc::Channel>& channel, const std::string& method,
                         const std::string& bytes) {
  std::string response;
  return GenericUnaryCall(channel, method, bytes, std::chrono::seconds(10), &response);
}

class RpcMetricsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    auto scenario = env::MakeScenario(env::ScenarioConfig{}, env::DefaultMapDir());
    ASSERT_TRUE(scenario.ok()) << scenario.status();
    scenario_ = *std::move(scenario);
    learner::LearnerConfig config;
    config.synchronous = false;
    learner::MutableOptions<learner::MappoOptions>(&config).ppo.hidden = 16;
    config.checkpoint_every = 0;
    config.checkpoint_seconds = 0;
    auto learner = learner::Learner::Create(scenario_.get(), config);
    ASSERT_TRUE(learner.ok()) << learner.status();
    learner_ = *std::move(learner);
    service_ = std::make_unique<learner::LearnerServiceImpl>(learner_.get());
    ServerOptions options;
    options.rpc_metrics = &server_metrics_;
    auto server = StartServer("127.0.0.1:0", {service_.get()}, &port_, options);
    ASSERT_TRUE(server.ok()) << server.status();
    server_ = *std::move(server);
    auto channel = MakeChannel(absl::StrCat("127.0.0.1:", port_), TransportConfig{}, &client_metrics_);
    ASSERT_TRUE(channel.ok()) << channel.status();
    channel_ = *channel;
  }
  void TearDown() override { server_->Shutdown(DeadlineIn(std::chrono::seconds(1))); }

  metrics::Registry server_registry_, client_registry_;
  RpcMetrics server_metrics_{RpcMetrics::Side::kServer, {"imca.v1.LearnerService"}, &server_registry_};
  RpcMetrics client_metrics_{RpcMetrics::Side::kClient, {"imca.v1.LearnerService"}, &client_registry_};
  std::unique_ptr<env::Scenario> scenario_;
  std::unique_ptr<learner::Learner> learner_;
  std::unique_ptr<learner::LearnerServiceImpl> service_;
  std::unique_ptr<grpc::Server> server_;
  std::shared_ptr<grpc::Channel> channel_;
  int port_ = 0;
};

TEST_F(RpcMetricsTest, CountsEachCallByMethodAndCodeOnBothSides) {
  auto stub = v1::LearnerService::NewStub(channel_);
  for (int i = 0; i < 3; ++i) {
    grpc::ClientContext context;
    v1::LearnerStatus status;
    ASSERT_TRUE(stub->GetStatus(&context, v1::GetStatusRequest(), &status).ok());
  }
  {
    grpc::ClientContext context;
    v1::GetPolicyRequest request;
    request.set_wait_ms(-1);
    v1::Policy policy;
    EXPECT_EQ(stub->GetPolicy(&context, request, &policy).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  }
  // The server's status is sent before the client sees it: wait for the
  // server side's count rather than race it.
  const std::string ok = R"(service="imca.v1.LearnerService",method="GetStatus",code="OK"})";
  for (int i = 0; i < 200 && SampleValue(server_registry_.Text(), "imca_rpc_server_handled_total{" + ok) < 3; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  for (const auto& [side, registry] : {std::pair{"server", &server_registry_}, {"client", &client_registry_}}) {
    const std::string text = registry->Text();
    const std::string family = absl::StrCat("imca_rpc_", side, "_");
    EXPECT_EQ(SampleValue(text, family + "handled_total{" + ok), 3) << side << "\n" << text;
    EXPECT_EQ(SampleValue(text, family + "handled_total{" +
                               R"(service="imca.v1.LearnerService",method="GetPolicy",code="INVALID_ARGUMENT"})"),
              1)
        << side;
    EXPECT_EQ(SampleValue(text, family + R"(started_total{service="imca.v1.LearnerService",method="GetStatus"})"), 3)
        << side;
    // One latency observation per completed call, each well under a second.
    EXPECT_EQ(SampleValue(text, family + R"(handling_seconds_count{service="imca.v1.LearnerService",method="GetStatus"})"),
              3)
        << side;
    EXPECT_EQ(SampleValue(text, family + R"(handling_seconds_bucket{service="imca.v1.LearnerService",method="GetStatus",le="0.512"})"),
              3)
        << side;
    // Every method has its series from the start (at zero), health included.
    EXPECT_EQ(SampleValue(text, family + R"(started_total{service="imca.v1.LearnerService",method="PushUnrolls"})"), 0)
        << side;
    EXPECT_EQ(SampleValue(text, family + R"(started_total{service="grpc.health.v1.Health",method="Check"})"), 0) << side;
  }
}

TEST_F(RpcMetricsTest, MethodsOfUnknownServicesAreCountedAsOtherSoNoClientAddsSeries) {
  for (const char* method : {"/imca.v1.Invented/A", "/x.Y/B"}) {
    EXPECT_EQ(GenericCall(channel_, method, "").error_code(), grpc::StatusCode::UNIMPLEMENTED);
  }
  const std::string client = client_registry_.Text();
  EXPECT_EQ(SampleValue(client, R"(imca_rpc_client_handled_total{service="other",method="other",code="UNIMPLEMENTED"})"), 2)
      << client;
  EXPECT_THAT(client, Not(HasSubstr("Invented")));
  // The server never names them either (gRPC answers unknown methods itself).
  EXPECT_THAT(server_registry_.Text(), Not(HasSubstr("Invented")));
}

TEST(RpcMetricsIndexTest, KnowsTheServicesMethodsFromTheDescriptorPool) {
  metrics::Registry registry;
  RpcMetrics m(RpcMetrics::Side::kServer, {"imca.v1.LearnerService", "imca.v1.NoSuchService"}, &registry);
  const int other = m.MethodIndex("/x/y");
  EXPECT_NE(m.MethodIndex("/imca.v1.LearnerService/PushUnrolls"), other);
  EXPECT_NE(m.MethodIndex("/imca.v1.LearnerService/GetPolicy"), m.MethodIndex("/imca.v1.LearnerService/GetStatus"));
  EXPECT_NE(m.MethodIndex("/grpc.health.v1.Health/Check"), other);
  EXPECT_EQ(m.MethodIndex("/imca.v1.NoSuchService/A"), other);
  EXPECT_EQ(m.MethodIndex(nullptr), other);
}

}  // namespace
}  // namespace imca

namespace imca {
namespace {

// A call gRPC refuses before any handler runs (over --max_receive_mb) never
// reaches the server's interceptors: it is counted at the client only
// (docs/metrics.md says so).
TEST(RpcMetricsRefusedTest, AnOversizedRequestIsCountedAtTheClientOnly) {
  auto scenario = env::MakeScenario(env::ScenarioConfig{}, env::DefaultMapDir());
  ASSERT_TRUE(scenario.ok());
  learner::LearnerConfig config;
  config.synchronous = false;
  learner::MutableOptions<learner::MappoOptions>(&config).ppo.hidden = 16;
  auto learner = learner::Learner::Create(scenario->get(), config);
  ASSERT_TRUE(learner.ok());
  learner::LearnerServiceImpl service(learner->get());
  metrics::Registry server_registry, client_registry;
  RpcMetrics server_metrics(RpcMetrics::Side::kServer, {"imca.v1.LearnerService"}, &server_registry);
  RpcMetrics client_metrics(RpcMetrics::Side::kClient, {"imca.v1.LearnerService"}, &client_registry);
  ServerOptions options;
  options.rpc_metrics = &server_metrics;
  options.max_receive_bytes = 1 << 10;
  int port = 0;
  auto server = StartServer("127.0.0.1:0", {&service}, &port, options);
  ASSERT_TRUE(server.ok());
  auto channel = MakeChannel(absl::StrCat("127.0.0.1:", port), TransportConfig{}, &client_metrics);
  ASSERT_TRUE(channel.ok());
  EXPECT_EQ(GenericCall(*channel, "/imca.v1.LearnerService/GetPolicy", std::string(4096, 'x')).error_code(),
            grpc::StatusCode::RESOURCE_EXHAUSTED);
  (*server)->Shutdown(DeadlineIn(std::chrono::seconds(1)));  // Every server-side hook has run.
  const std::string get_policy = R"(service="imca.v1.LearnerService",method="GetPolicy")";
  EXPECT_EQ(SampleValue(client_registry.Text(), "imca_rpc_client_handled_total{" + get_policy + R"(,code="RESOURCE_EXHAUSTED"})"),
            1);
  EXPECT_EQ(SampleValue(server_registry.Text(), "imca_rpc_server_started_total{" + get_policy + "}"), 0);
  EXPECT_THAT(server_registry.Text(), Not(HasSubstr("RESOURCE_EXHAUSTED")));
}

}  // namespace
}  // namespace imca
