// ./imca bench env: joint env steps/s of every scenario on one core,
// vectorised over 256 environments (or each count given after ROUNDS) with
// pre-drawn uniform random actions (the benchmark measures stepping, not
// sampling). Median of timed rounds. The second figure adds featurising
// every new state (each agent's observation and the global state), which an
// actor and the Python binding's step do too.
//   bench_env [ROUNDS [ENVS...]]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <vector>

#include "common/base/rng.h"
#include "common/env/env.h"
#include "common/env/featurizer.h"
#include "common/env/vec_env.h"

namespace imca {
namespace {

// Median joint steps/s of `rounds` rounds of 2000 steps of `envs` envs,
// featurising each new state when `featurize`.
double MedianRate(const env::Scenario& s, int envs, int rounds, bool featurize) {
  using Clock = std::chrono::steady_clock;
  const int steps = 2000;
  const int n = s.num_agents(), k = s.state_size();
  env::VecEnv vec(&s, envs, 1);
  std::vector<int32_t> pool(std::max(1 << 16, 16 * envs * n)), reached(envs * k);
  std::vector<float> rewards(envs * n);
  std::unique_ptr<bool[]> term(new bool[envs]), trunc(new bool[envs]);
  const env::Featurizer featurizer(s);
  const int d = featurizer.obs_dim(), g = featurizer.global_dim();
  std::vector<float> obs(static_cast<size_t>(envs) * n * d), global(static_cast<size_t>(envs) * g);
  Rng rng(5);
  for (int32_t& u : pool) u = static_cast<int32_t>(rng.Uniform(s.num_actions()));
  std::vector<double> rates;
  size_t offset = 0;
  for (int r = 0; r < rounds; ++r) {
    const auto start = Clock::now();
    for (int t = 0; t < steps; ++t) {
      offset = (offset + envs * n) % (pool.size() - envs * n);
      vec.Step(pool.data() + offset, rewards.data(), term.get(), trunc.get(), reached.data());
      if (!featurize) continue;
      for (int e = 0; e < envs; ++e) {
        const int32_t* state = vec.states() + static_cast<size_t>(e) * k;
        for (int a = 0; a < n; ++a) featurizer.Observe(state, a, &obs[(static_cast<size_t>(e) * n + a) * d]);
        featurizer.GlobalState(state, &global[static_cast<size_t>(e) * g]);
      }
    }
    rates.push_back(double{steps} * envs / std::chrono::duration<double>(Clock::now() - start).count());
  }
  std::sort(rates.begin(), rates.end());
  return rates[rates.size() / 2];
}

}  // namespace
}  // namespace imca

int main(int argc, char** argv) {
  using namespace imca;
  const int rounds = argc > 1 ? std::max(3, std::atoi(argv[1])) : 7;
  std::vector<int> env_counts;
  for (int i = 2; i < argc; ++i) {
    env_counts.push_back(std::atoi(argv[i]));
    if (env_counts.back() < 1) {
      std::fprintf(stderr, "bench_env: ENVS must be a whole number >= 1, got '%s'\n", argv[i]);
      return 2;
    }
  }
  if (env_counts.empty()) env_counts.push_back(256);
  std::printf("%-14s %6s %6s %16s %12s %22s\n", "scenario", "agents", "envs", "joint_steps/s", "ns/step",
              "featurised_steps/s");
  for (const std::string& name : env::ScenarioNames()) {
    env::ScenarioConfig config;
    config.name = name;
    auto scenario = env::MakeScenario(config, env::DefaultMapDir());
    if (!scenario.ok()) {
      std::fprintf(stderr, "%s\n", std::string(scenario.status().message()).c_str());
      return 1;
    }
    for (const int envs : env_counts) {
      const double median = MedianRate(**scenario, envs, rounds, false);
      const double featurised = MedianRate(**scenario, envs, rounds, true);
      std::printf("%-14s %6d %6d %16.0f %12.1f %22.0f\n", name.c_str(), (*scenario)->num_agents(), envs, median,
                  1e9 / median, featurised);
    }
  }
  return 0;
}
