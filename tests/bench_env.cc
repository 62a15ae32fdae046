// ./imca bench env: joint env steps/s of every scenario on one core,
// vectorised over 256 environments with pre-drawn uniform random actions
// (the benchmark measures stepping, not sampling). Median of timed rounds.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <vector>

#include "common/env.h"
#include "common/rng.h"
#include "common/vec_env.h"

int main(int argc, char** argv) {
  using namespace imca;
  using Clock = std::chrono::steady_clock;
  const int rounds = argc > 1 ? std::max(3, std::atoi(argv[1])) : 7;
  const int envs = 256, steps = 2000;
  std::printf("%-14s %6s %16s %12s\n", "scenario", "agents", "joint_steps/s", "ns/step");
  for (const std::string& name : env::ScenarioNames()) {
    env::ScenarioConfig config;
    config.name = name;
    auto scenario = env::MakeScenario(config, env::DefaultMapDir());
    if (!scenario.ok()) {
      std::fprintf(stderr, "%s\n", std::string(scenario.status().message()).c_str());
      return 1;
    }
    const env::Scenario& s = **scenario;
    const int n = s.num_agents(), k = s.state_size();
    env::VecEnv vec(&s, envs, 1);
    std::vector<int32_t> pool(1 << 16), reached(envs * k);
    std::vector<float> rewards(envs * n);
    std::unique_ptr<bool[]> term(new bool[envs]), trunc(new bool[envs]);
    Rng rng(5);
    for (int32_t& u : pool) u = static_cast<int32_t>(rng.Uniform(s.num_actions()));
    std::vector<double> rates;
    size_t offset = 0;
    for (int r = 0; r < rounds; ++r) {
      const auto start = Clock::now();
      for (int t = 0; t < steps; ++t) {
        offset = (offset + envs * n) % (pool.size() - envs * n);
        vec.Step(pool.data() + offset, rewards.data(), term.get(), trunc.get(), reached.data());
      }
      rates.push_back(double{steps} * envs / std::chrono::duration<double>(Clock::now() - start).count());
    }
    std::sort(rates.begin(), rates.end());
    const double median = rates[rates.size() / 2];
    std::printf("%-14s %6d %16.0f %12.1f\n", name.c_str(), n, median, 1e9 / median);
  }
  return 0;
}
