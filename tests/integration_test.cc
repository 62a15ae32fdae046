// The three real binaries as separate processes over loopback gRPC.
#include <signal.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_split.h"
#include "common/env/env.h"
#include "common/protocol/test_unrolls.h"
#include "common/rpc/grpc_util.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "imca/v1/learner_service.grpc.pb.h"
#include "imca/v1/reward_service.grpc.pb.h"
#include "tests/subprocess.h"

namespace imca {
namespace {

namespace fs = std::filesystem;
using testing::Subprocess;
using testing::WaitForPortFile;

const std::string kBin = IMCA_BIN_DIR;

std::string TempDir(const std::string& name) {
  const fs::path dir = fs::path(::testing::TempDir()) / ("imca_" + name + "_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir.string();
}

std::unique_ptr<Subprocess> StartRewardServer(const std::string& dir, const std::string& credit,
                                              int* port) {
  auto server = std::make_unique<Subprocess>(
      std::vector<std::string>{kBin + "/reward_server", "--listen=127.0.0.1:0",
                               "--port_file=" + dir + "/reward.port", "--credit=" + credit,
                               "--snapshot=" + dir + "/reward_snapshot.bin"},
      dir + "/reward_server.log");
  EXPECT_TRUE(server->Start());
  *port = WaitForPortFile(dir + "/reward.port", *server, std::chrono::seconds(30));
  EXPECT_GT(*port, 0) << server->Log();
  return server;
}

// A learner on a free port with `flags` after the listen and port-file flags.
std::unique_ptr<Subprocess> StartLearner(const std::string& dir, const std::vector<std::string>& flags, int* port) {
  std::vector<std::string> argv = {kBin + "/learner", "--listen=127.0.0.1:0", "--port_file=" + dir + "/learner.port"};
  argv.insert(argv.end(), flags.begin(), flags.end());
  auto learner = std::make_unique<Subprocess>(argv, dir + "/learner.log");
  EXPECT_TRUE(learner->Start());
  *port = WaitForPortFile(dir + "/learner.port", *learner, std::chrono::seconds(60));
  EXPECT_GT(*port, 0) << learner->Log();
  return learner;
}

// `count` actors "actor-<i>" with 8 envs x 32-step unrolls, seeds 1.., and `flags`.
std::vector<std::unique_ptr<Subprocess>> StartActors(const std::string& dir, int count, int learner_port,
                                                     int reward_port, const std::vector<std::string>& flags = {}) {
  std::vector<std::unique_ptr<Subprocess>> actors;
  for (int i = 0; i < count; ++i) {
    std::vector<std::string> argv = {kBin + "/actor", "--learner=127.0.0.1:" + std::to_string(learner_port),
                                     "--reward_server=127.0.0.1:" + std::to_string(reward_port), "--envs=8",
                                     "--unroll_length=32", "--seed=" + std::to_string(i + 1),
                                     "--actor_id=actor-" + std::to_string(i)};
    argv.insert(argv.end(), flags.begin(), flags.end());
    actors.push_back(std::make_unique<Subprocess>(argv, dir + "/actor-" + std::to_string(i) + ".log"));
    EXPECT_TRUE(actors.back()->Start());
  }
  return actors;
}

v1::ScoreResponse DryRunScore(int port, const env::Scenario& scenario) {
  auto stub = v1::RewardService::NewStub(MakeChannel("127.0.0.1:" + std::to_string(port)));
  v1::ScoreRequest request;
  *request.mutable_unroll() = testing::RandomUnroll(scenario, 16, 4, 99);
  request.set_dry_run(true);
  grpc::ClientContext context;
  context.set_deadline(DeadlineIn(std::chrono::seconds(10)));
  v1::ScoreResponse response;
  const grpc::Status status = stub->Score(&context, request, &response);
  EXPECT_TRUE(status.ok()) << status.error_message();
  return response;
}

// The rows of a metrics.csv as column -> value.
std::vector<std::map<std::string, double>> ReadMetrics(const std::string& path) {
  std::ifstream in(path);
  std::string header, line;
  std::getline(in, header);
  const std::vector<std::string> names = absl::StrSplit(header, ',');
  std::vector<std::map<std::string, double>> rows;
  while (std::getline(in, line)) {
    const std::vector<std::string> values = absl::StrSplit(line, ',');
    EXPECT_EQ(values.size(), names.size()) << line;
    std::map<std::string, double>& row = rows.emplace_back();
    for (size_t i = 0; i < names.size() && i < values.size(); ++i) {
      EXPECT_TRUE(absl::SimpleAtod(values[i], &row[names[i]])) << names[i];
    }
  }
  return rows;
}

std::unique_ptr<env::Scenario> DefaultScenario() {
  auto scenario = env::MakeScenario(env::ScenarioConfig{}, env::DefaultMapDir());
  EXPECT_TRUE(scenario.ok());
  return *std::move(scenario);
}

TEST(IntegrationTest, ThreeServicesTrainAndStopCleanly) {
  const std::string dir = TempDir("pipeline");
  const auto scenario = DefaultScenario();
  int reward_port = 0;
  auto reward_server = StartRewardServer(dir, "imca", &reward_port);
  ASSERT_GT(reward_port, 0);

  int learner_port = 0;
  auto learner_process = StartLearner(dir, {"--run_dir=" + dir + "/run", "--steps=0", "--batch_steps=1024",
                                            "--checkpoint_every=2"},
                                      &learner_port);
  ASSERT_GT(learner_port, 0);
  Subprocess& learner = *learner_process;
  auto actors = StartActors(dir, 2, learner_port, reward_port);

  auto learner_stub = v1::LearnerService::NewStub(MakeChannel("127.0.0.1:" + std::to_string(learner_port)));
  v1::LearnerStatus status;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(180);
  while (std::chrono::steady_clock::now() < deadline) {
    grpc::ClientContext context;
    context.set_deadline(DeadlineIn(std::chrono::seconds(5)));
    ASSERT_TRUE(learner_stub->GetStatus(&context, v1::GetStatusRequest(), &status).ok());
    if (status.policy_version() >= 4 && status.actors_seen_size() == 2) break;
    for (auto& actor : actors) ASSERT_FALSE(actor->Poll()) << actor->Log();
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  EXPECT_GE(status.policy_version(), 4);
  EXPECT_THAT(status.actors_seen(), ::testing::UnorderedElementsAre("actor-0", "actor-1"));
  EXPECT_GE(status.env_steps(), 4 * 1024);

  // The reward server scored what the actors sent.
  auto reward_stub = v1::RewardService::NewStub(MakeChannel("127.0.0.1:" + std::to_string(reward_port)));
  grpc::ClientContext stats_context;
  v1::RewardStats stats;
  ASSERT_TRUE(reward_stub->GetStats(&stats_context, v1::GetStatsRequest(), &stats).ok());
  EXPECT_GE(stats.transitions_scored(), status.env_steps());
  EXPECT_GT(stats.distinct_keys(), 100);

  // Bonuses are non-zero and split by imca's softmax shares.
  const v1::ScoreResponse response = DryRunScore(reward_port, *scenario);
  int uneven = 0;
  for (int i = 0; i < response.num_transitions(); ++i) {
    EXPECT_GT(response.global_rewards(i), 0.0f);
    EXPECT_NEAR(response.agent_rewards(2 * i) + response.agent_rewards(2 * i + 1), response.global_rewards(i), 1e-5);
    EXPECT_NEAR(response.agent_rewards(2 * i), response.shares(2 * i) * response.global_rewards(i), 1e-5);
    uneven += std::abs(response.shares(2 * i) - 0.5f) > 1e-3f;
  }
  EXPECT_GT(uneven, 0) << "after training, some transitions must credit one agent more";

  // The learner's metrics saw the intrinsic rewards the reward server gave.
  std::ifstream metrics(dir + "/run/metrics.csv");
  std::string header, row, last;
  std::getline(metrics, header);
  while (std::getline(metrics, row)) last = row;
  ASSERT_FALSE(last.empty());
  const std::vector<std::string> names = absl::StrSplit(header, ',');
  const std::vector<std::string> values = absl::StrSplit(last, ',');
  ASSERT_EQ(names.size(), values.size()) << header << "\n" << last;
  std::map<std::string, double> column;
  for (size_t i = 0; i < names.size(); ++i) ASSERT_TRUE(absl::SimpleAtod(values[i], &column[names[i]])) << names[i];
  EXPECT_GT(column["intrinsic_reward"], 0);
  EXPECT_GT(column["global_reward"], 0);
  EXPECT_GT(column["contribution_abs"], 0);
  EXPECT_GE(column["share_max"], 0.5);
  EXPECT_NEAR(column["share_1"] + column["share_2"], 1.0, 2e-4);

  for (auto& actor : actors) {
    actor->Signal(SIGTERM);
    EXPECT_EQ(actor->Wait(std::chrono::seconds(30)), 0) << actor->Log();
  }
  learner.Signal(SIGTERM);
  EXPECT_EQ(learner.Wait(std::chrono::seconds(60)), 0) << learner.Log();
  reward_server->Signal(SIGTERM);
  EXPECT_EQ(reward_server->Wait(std::chrono::seconds(30)), 0) << reward_server->Log();
  EXPECT_TRUE(fs::exists(dir + "/reward_snapshot.bin"));
  bool checkpoint = false;
  for (const auto& entry : fs::directory_iterator(dir + "/run/checkpoints")) {
    checkpoint |= entry.path().extension() == ".pt";
  }
  EXPECT_TRUE(checkpoint);
}

// Synchronous collection: the actors wait for each new policy, so every
// iteration trains on unrolls acted by exactly the policy it starts from:
// lag 0, and the recorded behaviour probabilities are the learner's own
// (behaviour_kl would be > 0 if the ratio's old policy were another).
TEST(IntegrationTest, SynchronousActorsActWithThePolicyTheLearnerTrains) {
  const std::string dir = TempDir("synchronous");
  int reward_port = 0;
  auto reward_server = StartRewardServer(dir, "imca", &reward_port);
  ASSERT_GT(reward_port, 0);
  int learner_port = 0;
  auto learner = StartLearner(dir, {"--run_dir=" + dir + "/run", "--steps=8192", "--batch_steps=1024", "--synchronous=true"},
                              &learner_port);
  ASSERT_GT(learner_port, 0);
  // 2 actors x 8 envs x 32 steps x 2 unrolls = 1024 steps: one batch per version.
  auto actors = StartActors(dir, 2, learner_port, reward_port, {"--sync_unrolls=2"});
  EXPECT_EQ(learner->Wait(std::chrono::seconds(180)), 0) << learner->Log();
  for (auto& actor : actors) EXPECT_EQ(actor->Wait(std::chrono::seconds(30)), 0) << actor->Log();
  reward_server->Signal(SIGTERM);
  EXPECT_EQ(reward_server->Wait(std::chrono::seconds(30)), 0) << reward_server->Log();
  const auto rows = ReadMetrics(dir + "/run/metrics.csv");
  ASSERT_EQ(rows.size(), 8u);
  for (const auto& row : rows) {
    EXPECT_EQ(row.at("policy_lag"), 0.0) << "iteration " << row.at("iteration");
    EXPECT_LT(std::abs(row.at("behaviour_kl")), 1e-6) << "iteration " << row.at("iteration");
    EXPECT_EQ(row.at("dropped_stale"), 0.0) << "iteration " << row.at("iteration");
  }
}

TEST(IntegrationTest, EachCreditModeSplitsAsDocumented) {
  const auto scenario = DefaultScenario();
  for (const std::string credit : {"none", "shared", "independent"}) {
    const std::string dir = TempDir("credit_" + credit);
    int port = 0;
    auto server = StartRewardServer(dir, credit, &port);
    ASSERT_GT(port, 0);
    const v1::ScoreResponse r = DryRunScore(port, *scenario);
    for (int i = 0; i < r.num_transitions(); ++i) {
      const float a = r.agent_rewards(2 * i), b = r.agent_rewards(2 * i + 1);
      if (credit == "none") {
        EXPECT_EQ(a, 0.0f);
        EXPECT_EQ(b, 0.0f);
      } else if (credit == "shared") {
        EXPECT_GT(a, 0.0f);
        EXPECT_EQ(a, r.global_rewards(i));
        EXPECT_EQ(b, r.global_rewards(i));
      } else {
        EXPECT_GT(a, 0.0f);
        EXPECT_NEAR(a + b, r.global_rewards(i), 1e-5);  // Reported as the team sum.
      }
    }
    server->Signal(SIGTERM);
    EXPECT_EQ(server->Wait(std::chrono::seconds(30)), 0) << server->Log();
  }
}

// Every scenario trains through the real services until the learner's budget.
class ScenarioPipelineTest : public ::testing::TestWithParam<std::string> {};

TEST_P(ScenarioPipelineTest, TrainsToTheBudgetAndStops) {
  const std::string scenario = GetParam();
  const std::string dir = TempDir("scenario_" + scenario);
  Subprocess reward_server({kBin + "/reward_server", "--listen=127.0.0.1:0", "--port_file=" + dir + "/reward.port",
                            "--scenario=" + scenario},
                           dir + "/reward_server.log");
  ASSERT_TRUE(reward_server.Start());
  const int reward_port = WaitForPortFile(dir + "/reward.port", reward_server, std::chrono::seconds(30));
  ASSERT_GT(reward_port, 0) << reward_server.Log();
  Subprocess learner({kBin + "/learner", "--listen=127.0.0.1:0", "--port_file=" + dir + "/learner.port",
                      "--scenario=" + scenario, "--run_dir=" + dir + "/run", "--steps=3072", "--batch_steps=1024",
                      "--actors=1"},
                     dir + "/learner.log");
  ASSERT_TRUE(learner.Start());
  const int learner_port = WaitForPortFile(dir + "/learner.port", learner, std::chrono::seconds(60));
  ASSERT_GT(learner_port, 0) << learner.Log();
  Subprocess actor({kBin + "/actor", "--learner=127.0.0.1:" + std::to_string(learner_port),
                    "--reward_server=127.0.0.1:" + std::to_string(reward_port), "--scenario=" + scenario,
                    "--envs=8", "--unroll_length=32", "--actor_id=actor-" + scenario},
                   dir + "/actor.log");
  ASSERT_TRUE(actor.Start());
  EXPECT_EQ(learner.Wait(std::chrono::seconds(120)), 0) << learner.Log() << actor.Log();
  // The actor learns that the budget is done and stops by itself.
  EXPECT_EQ(actor.Wait(std::chrono::seconds(30)), 0) << actor.Log();
  reward_server.Signal(SIGTERM);
  EXPECT_EQ(reward_server.Wait(std::chrono::seconds(30)), 0) << reward_server.Log();
  std::ifstream metrics(dir + "/run/metrics.csv");
  int rows = -1;
  for (std::string line; std::getline(metrics, line);) ++rows;
  EXPECT_EQ(rows, 3) << "one metrics row per iteration";
}

INSTANTIATE_TEST_SUITE_P(AllScenarios, ScenarioPipelineTest, ::testing::ValuesIn(env::ScenarioNames()),
                         [](const ::testing::TestParamInfo<std::string>& info) { return info.param; });

// The paper's pairings: predator_prey + RND, multi_room + SF.
class LearnedRewardTest : public ::testing::TestWithParam<std::pair<std::string, std::string>> {};

TEST_P(LearnedRewardTest, ServerCreditsLearnedNoveltyAndSnapshots) {
  const auto [scenario_name, kind] = GetParam();
  const std::string dir = TempDir(kind);
  Subprocess server({kBin + "/reward_server", "--listen=127.0.0.1:0", "--port_file=" + dir + "/reward.port",
                     "--scenario=" + scenario_name, "--reward=" + kind, "--credit=imca",
                     "--snapshot=" + dir + "/snapshot.pt"},
                    dir + "/reward_server.log");
  ASSERT_TRUE(server.Start());
  const int port = WaitForPortFile(dir + "/reward.port", server, std::chrono::seconds(30));
  ASSERT_GT(port, 0) << server.Log();
  env::ScenarioConfig config;
  config.name = scenario_name;
  auto scenario = env::MakeScenario(config, env::DefaultMapDir());
  ASSERT_TRUE(scenario.ok());
  const v1::ScoreResponse r = DryRunScore(port, **scenario);
  const int n = (*scenario)->num_agents();
  ASSERT_EQ(r.num_agents(), n);
  int positive = 0;
  for (int i = 0; i < r.num_transitions(); ++i) {
    float sum = 0, shares = 0;
    for (int a = 0; a < n; ++a) {
      sum += r.agent_rewards(n * i + a);
      shares += r.shares(n * i + a);
    }
    positive += r.global_rewards(i) > 0;
    EXPECT_NEAR(shares, 1.0f, 1e-5);
    // RND splits R_i exactly; SF also divides by sqrt(N_ep) >= 1.
    EXPECT_LE(sum, r.global_rewards(i) * (1 + 1e-4f) + 1e-6f);
    if (kind == "rnd") {
      EXPECT_NEAR(sum, r.global_rewards(i), 1e-4 * r.global_rewards(i) + 1e-6);
    }
  }
  EXPECT_GT(positive, r.num_transitions() / 2);
  server.Signal(SIGTERM);
  EXPECT_EQ(server.Wait(std::chrono::seconds(30)), 0) << server.Log();
  EXPECT_TRUE(fs::exists(dir + "/snapshot.pt"));
}

INSTANTIATE_TEST_SUITE_P(PaperPairings, LearnedRewardTest,
                         ::testing::Values(std::make_pair(std::string("predator_prey"), std::string("rnd")),
                                           std::make_pair(std::string("multi_room"), std::string("sf"))),
                         [](const auto& info) { return info.param.second; });

TEST(IntegrationTest, PortInUseIsAOneLineError) {
  const std::string dir = TempDir("port");
  int port = 0;
  auto first = StartRewardServer(dir, "imca", &port);
  ASSERT_GT(port, 0);
  Subprocess second({kBin + "/reward_server", "--listen=127.0.0.1:" + std::to_string(port)},
                    dir + "/second.log");
  ASSERT_TRUE(second.Start());
  EXPECT_EQ(second.Wait(std::chrono::seconds(30)), 2);
  EXPECT_THAT(second.Log(), ::testing::HasSubstr("--listen: cannot listen on 127.0.0.1:" + std::to_string(port)));
  first->Signal(SIGTERM);
  EXPECT_EQ(first->Wait(std::chrono::seconds(30)), 0);
}

}  // namespace
}  // namespace imca
