// ./imca bench speed: the component ceilings of the pipeline, printed as
// medians over repeated timed rounds (run by hand, never in CI).
//   env:     joint env steps/s of coop_nav, vectorised, on one core
//   score:   transitions/s through RewardService.Score over loopback gRPC
//            (count + imca, 2 agents, one unroll of 64 x 32 per call)
//   learner: joint env steps/s the learner trains on when fed pre-made
//            unrolls as fast as it takes them (the ceiling for end-to-end)
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <memory>
#include <thread>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "actor/actor.h"
#include "common/base/rng.h"
#include "common/env/env.h"
#include "common/env/vec_env.h"
#include "common/nn/blas_kernels.h"
#include "common/protocol/test_unrolls.h"
#include "common/rpc/grpc_util.h"
#include "learner/algorithms/mappo/mappo_options.h"
#include "learner/algorithms/registry.h"
#include "learner/learner.h"
#include "reward_server/make_scorer.h"
#include "reward_server/novelty/count_table.h"
#include "reward_server/reward_service.h"

namespace imca {
namespace {

using Clock = std::chrono::steady_clock;

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

double Seconds(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

double BenchEnv(const env::Scenario& scenario, int rounds) {
  const int envs = 256, n = scenario.num_agents(), k = scenario.state_size();
  env::VecEnv vec(&scenario, envs, 1);
  std::vector<int32_t> actions(envs * n), reached(envs * k);
  std::vector<float> rewards(envs * n);
  std::unique_ptr<bool[]> term(new bool[envs]), trunc(new bool[envs]);
  // Pre-drawn actions: the benchmark measures stepping, not sampling.
  std::vector<int32_t> pool(1 << 16);
  Rng rng(5);
  for (int32_t& u : pool) u = static_cast<int32_t>(rng.Uniform(5));
  std::vector<double> rates;
  size_t offset = 0;
  for (int r = 0; r < rounds; ++r) {
    const int steps = 2000;
    const auto start = Clock::now();
    for (int s = 0; s < steps; ++s) {
      offset = (offset + envs * n) % (pool.size() - envs * n);
      vec.Step(pool.data() + offset, rewards.data(), term.get(), trunc.get(), reached.data());
    }
    rates.push_back(static_cast<double>(steps) * envs / Seconds(start));
  }
  return Median(rates);
}

double BenchScore(const env::Scenario& scenario, int rounds) {
  reward::ScorerConfig config;
  config.credit = "imca";
  std::unique_ptr<reward::Scorer> scorer = *reward::MakeScorer("count", scenario, config);
  reward::RewardServiceImpl service(&scenario, scorer.get(), "count", config, "");
  int port = 0;
  auto server = StartServer("127.0.0.1:0", {&service}, &port);
  if (!server.ok()) return 0;
  auto stub = v1::RewardService::NewStub(MakeChannel("127.0.0.1:" + std::to_string(port)));
  std::vector<v1::ScoreRequest> requests(8);
  for (size_t i = 0; i < requests.size(); ++i) {
    *requests[i].mutable_unroll() = testing::RandomUnroll(scenario, 64, 32, 100 + i);
  }
  std::vector<double> rates;
  for (int r = 0; r < rounds; ++r) {
    const int calls = 40;
    const auto start = Clock::now();
    for (int c = 0; c < calls; ++c) {
      grpc::ClientContext context;
      context.set_deadline(DeadlineIn(std::chrono::seconds(10)));
      v1::ScoreResponse response;
      if (!stub->Score(&context, requests[c % requests.size()], &response).ok()) return 0;
    }
    rates.push_back(calls * 64.0 * 32.0 / Seconds(start));
  }
  (*server)->Shutdown();
  return Median(rates);
}

// Resident set size in MiB.
double RssMiB() {
  std::ifstream statm("/proc/self/statm");
  long pages = 0, resident = 0;
  statm >> pages >> resident;
  return resident * (sysconf(_SC_PAGESIZE) / 1048576.0);
}

// Tens of millions of keys: insert `keys` distinct keys, then probe them.
void BenchCountTable(int64_t keys) {
  const double rss_before = RssMiB();
  reward::CountTable table;
  uint64_t state = 1;
  auto start = Clock::now();
  for (int64_t i = 0; i < keys; ++i) table.Increment(Rng::SplitMix64(state));
  const double insert_s = Seconds(start);
  state = 1;
  start = Clock::now();
  uint64_t sum = 0;
  for (int64_t i = 0; i < keys; ++i) sum += table.Get(Rng::SplitMix64(state));
  const double probe_s = Seconds(start);
  std::printf("count_table_keys %lld\ncount_table_insert_ns %.1f\ncount_table_probe_ns %.1f\n"
              "count_table_rss_mib %.0f\ncount_table_counts_sum %llu\n",
              static_cast<long long>(table.size()), insert_s * 1e9 / keys, probe_s * 1e9 / keys,
              RssMiB() - rss_before, static_cast<unsigned long long>(sum));
}

// Prints the median over iterations of every ms_* column of a run's
// metrics.csv as "<prefix>_<column> <ms>": where an iteration's time goes.
void PrintPhases(const std::string& metrics_path, const std::string& prefix) {
  std::ifstream in(metrics_path);
  std::string line;
  if (!std::getline(in, line)) return;
  const std::vector<std::string> names = absl::StrSplit(line, ',');
  std::vector<std::vector<double>> columns(names.size());
  while (std::getline(in, line)) {
    const std::vector<std::string> cells = absl::StrSplit(line, ',');
    for (size_t i = 0; i < names.size() && i < cells.size(); ++i) {
      double v;
      if (absl::StartsWith(names[i], "ms_") && absl::SimpleAtod(cells[i], &v)) columns[i].push_back(v);
    }
  }
  double total = 0;
  for (size_t i = 0; i < names.size(); ++i) {
    if (columns[i].empty()) continue;
    const double m = Median(columns[i]);
    if (names[i] != "ms_wait" && names[i] != "ms_featurise") total += m;  // The training thread's.
    std::printf("%s_%s %.2f\n", prefix.c_str(), names[i].c_str(), m);
  }
  std::printf("%s_ms_busy %.2f\n", prefix.c_str(), total);
}

// The learner's shape of work: joint steps per iteration, unrolls of T x E.
struct LearnerShape {
  const char* name;  // "" for ./imca train's defaults, else a suffix.
  int64_t batch_steps;
  int unroll_length;
  int envs;
  bool separate_optimizers;
  bool concurrent_critic;
};
// The defaults on coop_nav (the bench's scenario: DefaultLearnerConfig,
// DefaultActorConfig), and those before the learner ablation and the
// concurrent critic (docs/benchmarks.md, "Sample efficiency against the
// reference MAPPO").
LearnerShape DefaultShape() {
  const learner::LearnerConfig learner = *learner::DefaultLearnerConfig("coop_nav", "mappo");
  const actor::ActorConfig actor = actor::DefaultActorConfig("coop_nav");
  return {"", learner.batch_steps, actor.unroll_length, actor.num_envs, learner::OptionsOf<learner::MappoOptions>(learner).ppo.separate_optimizers,
          learner::OptionsOf<learner::MappoOptions>(learner).ppo.concurrent_critic};
}
constexpr LearnerShape kV1Shape{"_v1", 8192, 64, 32, false, false};

double BenchLearner(const env::Scenario& scenario, int rounds, int threads, const LearnerShape& shape) {
  learner::LearnerConfig config;
  config.batch_steps = shape.batch_steps;
  config.synchronous = false;  // Update throughput: every pushed unroll is trained.
  config.run_dir = "/tmp/imca_bench_speed_learner_" + std::to_string(getpid());
  config.checkpoint_every = 0;
  config.threads = threads;
  learner::MutableOptions<learner::MappoOptions>(&config).ppo.separate_optimizers = shape.separate_optimizers;
  learner::MutableOptions<learner::MappoOptions>(&config).ppo.concurrent_critic = shape.concurrent_critic;
  config.max_policy_lag = 1 << 30;
  config.queue_capacity = 8;
  auto learner = learner::Learner::Create(&scenario, config);
  if (!learner.ok()) return 0;
  learner::Learner* l = learner->get();
  std::vector<v1::Unroll> unrolls;
  for (int i = 0; i < 8; ++i) {
    unrolls.push_back(testing::RandomUnroll(scenario, shape.unroll_length, shape.envs, 200 + i));
  }
  std::thread trainer([l] { l->Run().ok(); });
  std::vector<double> rates;
  int64_t pushed = 0;
  // Rounds of at least 32k steps, so that small iterations are timed over many.
  const int64_t per_round = std::max<int64_t>(4, 32768 / shape.batch_steps) * shape.batch_steps;
  for (int r = 0; r < rounds + 1; ++r) {
    const int64_t before = l->Status().env_steps();
    const auto start = Clock::now();
    while (l->Status().env_steps() < before + per_round) {
      v1::Unroll u = unrolls[pushed++ % unrolls.size()];
      u.set_policy_version(l->Status().policy_version());
      l->Push(std::move(u)).ok();
    }
    if (r > 0) rates.push_back((l->Status().env_steps() - before) / Seconds(start));  // r = 0 warms up.
  }
  l->Stop();
  trainer.join();
  PrintPhases(config.run_dir + "/metrics.csv",
              absl::StrCat("learner", shape.name, "_", threads, "thread"));
  std::filesystem::remove_all(config.run_dir);
  return Median(rates);
}

}  // namespace
}  // namespace imca

int main(int argc, char** argv) {
  imca::nn::UseTheCpusBlasKernels(argv);  // First: it may re-execute the binary.
  using namespace imca;
  const int rounds = argc > 1 ? std::max(3, std::atoi(argv[1])) : 7;
  auto scenario = env::MakeScenario(env::ScenarioConfig{}, env::DefaultMapDir());
  if (!scenario.ok()) return 1;
  std::printf("env_steps_per_sec %.0f\n", BenchEnv(**scenario, rounds));
  std::fflush(stdout);
  std::printf("score_transitions_per_sec %.0f\n", BenchScore(**scenario, rounds));
  std::fflush(stdout);
  for (const LearnerShape& shape : {DefaultShape(), kV1Shape}) {
    for (int threads : {1, 2}) {
      std::printf("learner%s_steps_per_sec_%dthread%s %.0f\n", shape.name, threads, threads > 1 ? "s" : "",
                  BenchLearner(**scenario, rounds, threads, shape));
      std::fflush(stdout);
    }
  }
  BenchCountTable(20'000'000);
  return 0;
}
