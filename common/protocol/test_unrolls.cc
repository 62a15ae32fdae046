#include "common/protocol/test_unrolls.h"

#include <cmath>
#include <vector>

#include "common/base/rng.h"
#include "common/env/vec_env.h"

namespace imca::testing {

v1::Unroll RandomUnroll(const env::Scenario& scenario, int length, int num_envs, uint64_t seed) {
  const int n = scenario.num_agents(), a_count = scenario.num_actions(), k = scenario.state_size();
  env::VecEnv envs(&scenario, num_envs, seed);
  Rng rng(seed + 1);
  v1::Unroll u;
  u.set_scenario(std::string(scenario.name()));
  u.set_actor_id("test");
  u.set_length(length);
  u.set_num_envs(num_envs);
  u.set_num_agents(n);
  u.set_num_actions(a_count);
  u.set_state_size(k);
  u.set_scenario_fingerprint(scenario.fingerprint());
  std::vector<int32_t> actions(num_envs * n), reached(num_envs * k);
  std::vector<float> rewards(num_envs * n);
  std::vector<char> terminated(num_envs), truncated(num_envs);
  for (int t = 0; t < length; ++t) {
    u.mutable_states()->Add(envs.states(), envs.states() + num_envs * k);
    for (int e = 0; e < num_envs; ++e) u.add_episode_ids(envs.episode_id(e));
    for (int32_t& a : actions) a = static_cast<int32_t>(rng.Uniform(a_count));
    envs.Step(actions.data(), rewards.data(), reinterpret_cast<bool*>(terminated.data()),
              reinterpret_cast<bool*>(truncated.data()), reached.data());
    u.mutable_actions()->Add(actions.begin(), actions.end());
    u.mutable_rewards()->Add(rewards.begin(), rewards.end());
    u.mutable_next_states()->Add(reached.begin(), reached.end());
    for (int e = 0; e < num_envs; ++e) {
      u.add_terminated(terminated[e]);
      u.add_truncated(truncated[e]);
    }
    for (int i = 0; i < num_envs * n; ++i) {
      u.add_behaviour_log_probs(-std::log(static_cast<float>(a_count)));
      for (int j = 0; j < a_count; ++j) u.add_action_probs(1.0f / a_count);
      u.add_intrinsic_rewards(0.0f);
    }
  }
  u.mutable_states()->Add(envs.states(), envs.states() + num_envs * k);
  return u;
}

}  // namespace imca::testing
