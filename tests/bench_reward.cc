// ./imca bench reward: Score throughput through loopback gRPC (one unroll of
// 64 steps x 32 envs per call) for count, RND and SF with 2 agents (coop_nav)
// and 4 agents (predator_prey), and the share of time imca's counterfactuals
// add (1 - time(shared) / time(imca), same kind and scenario). Medians.
//   bench_reward [ROUNDS [KIND SCENARIO]]  (with KIND and SCENARIO: that row alone)
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "common/env/env.h"
#include "common/nn/blas_kernels.h"
#include "common/protocol/test_unrolls.h"
#include "common/rpc/grpc_util.h"
#include "reward_server/make_scorer.h"
#include "reward_server/reward_service.h"

namespace imca {
namespace {

using Clock = std::chrono::steady_clock;

enum class Journal { kOff, kWrite, kSync };

// Median transitions/s of Score calls with `credit`; with a journal, the
// scorer is restored from (and journals to) a fresh snapshot path.
double Throughput(const std::string& kind, const env::Scenario& scenario, std::string credit, int rounds,
                  Journal journal = Journal::kOff) {
  reward::ScorerConfig config;
  config.credit = credit;
  auto made = reward::MakeScorer(kind, scenario, config);
  if (!made.ok()) {
    std::fprintf(stderr, "bench_reward: %s\n", std::string(made.status().message()).c_str());
    return 0;
  }
  std::unique_ptr<reward::Scorer> scorer = *std::move(made);
  const std::string dir = "/tmp/bench_reward_" + std::to_string(getpid());
  if (journal != Journal::kOff) {
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    if (!scorer->Restore(dir + "/snapshot.bin", journal == Journal::kSync).ok()) return 0;
  }
  reward::RewardServiceImpl service(&scenario, scorer.get(), kind, config, "");
  int port = 0;
  auto server = StartServer("127.0.0.1:0", {&service}, &port);
  if (!server.ok()) return 0;
  auto stub = v1::RewardService::NewStub(MakeChannel("127.0.0.1:" + std::to_string(port)));
  std::vector<v1::ScoreRequest> requests(4);
  for (size_t i = 0; i < requests.size(); ++i) {
    *requests[i].mutable_unroll() = testing::RandomUnroll(scenario, 64, 32, 300 + i);
  }
  std::vector<double> rates;
  for (int r = 0; r < rounds + 1; ++r) {
    const int calls = kind == "count" ? 40 : 8;
    const auto start = Clock::now();
    for (int c = 0; c < calls; ++c) {
      grpc::ClientContext context;
      context.set_deadline(DeadlineIn(std::chrono::seconds(60)));
      v1::ScoreResponse response;
      if (!stub->Score(&context, requests[c % requests.size()], &response).ok()) return 0;
    }
    if (r > 0) rates.push_back(calls * 64.0 * 32.0 / std::chrono::duration<double>(Clock::now() - start).count());
  }
  (*server)->Shutdown();
  scorer.reset();
  std::filesystem::remove_all(dir);
  std::sort(rates.begin(), rates.end());
  return rates[rates.size() / 2];
}

}  // namespace
}  // namespace imca

int main(int argc, char** argv) {
  imca::nn::UseTheCpusBlasKernels(argv);  // First: it may re-execute the binary.
  using namespace imca;
  const int rounds = argc > 1 ? std::max(3, std::atoi(argv[1])) : 5;
  if (argc != 2 && argc != 4 && argc != 1) {
    std::fprintf(stderr, "usage: bench_reward [ROUNDS [KIND SCENARIO]]\n");
    return 2;
  }
  const bool one_row = argc == 4;
  const std::vector<std::string> kinds = one_row ? std::vector<std::string>{argv[2]}
                                                 : std::vector<std::string>{"count", "rnd", "sf"};
  const std::vector<std::string> names = one_row ? std::vector<std::string>{argv[3]}
                                                 : std::vector<std::string>{"coop_nav", "predator_prey"};
  std::printf("%-6s %-14s %6s %18s %18s %16s\n", "kind", "scenario", "agents", "imca_trans/s", "shared_trans/s",
              "counterfactuals");
  for (const std::string& name : names) {
    env::ScenarioConfig config;
    config.name = name;
    auto scenario = env::MakeScenario(config, env::DefaultMapDir());
    if (!scenario.ok()) {
      std::fprintf(stderr, "bench_reward: %s\n", std::string(scenario.status().message()).c_str());
      return 2;
    }
    for (const std::string& kind : kinds) {
      const double imca = Throughput(kind, **scenario, "imca", rounds);
      const double shared = Throughput(kind, **scenario, "shared", rounds);
      if (imca == 0 || shared == 0) return 1;
      std::printf("%-6s %-14s %6d %18.0f %18.0f %15.0f%%\n", kind.c_str(), name.c_str(), (*scenario)->num_agents(),
                  imca, shared, 100.0 * (1.0 - imca / shared));
      std::fflush(stdout);
    }
  }
  if (one_row) return 0;
  // The count journal's cost (docs/reliability.md): imca credit, no journal,
  // the journal written before each answer, and fdatasync'ed as well.
  std::printf("\n%-6s %-14s %14s %14s %14s %9s %9s\n", "kind", "scenario", "off_trans/s", "journal_trans/s",
              "fsync_trans/s", "journal", "fsync");
  for (const char* name : {"coop_nav", "predator_prey"}) {
    env::ScenarioConfig config;
    config.name = name;
    auto scenario = env::MakeScenario(config, env::DefaultMapDir());
    if (!scenario.ok()) return 1;
    // Interleaved, three times each, the median of the three medians: the
    // machine's noise is larger than the journal's cost.
    std::vector<double> offs, writes, syncs;
    for (int repeat = 0; repeat < 3; ++repeat) {
      offs.push_back(Throughput("count", **scenario, "imca", rounds, Journal::kOff));
      writes.push_back(Throughput("count", **scenario, "imca", rounds, Journal::kWrite));
      syncs.push_back(Throughput("count", **scenario, "imca", rounds, Journal::kSync));
    }
    for (auto* v : {&offs, &writes, &syncs}) std::sort(v->begin(), v->end());
    const double off = offs[1], write = writes[1], sync = syncs[1];
    std::printf("%-6s %-14s %14.0f %14.0f %14.0f %8.1f%% %8.1f%%\n", "count", name, off, write, sync,
                100.0 * (1.0 - write / off), 100.0 * (1.0 - sync / off));
    std::fflush(stdout);
  }
  return 0;
}
