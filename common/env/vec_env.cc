#include "common/env/vec_env.h"

#include <cstring>

namespace imca::env {

VecEnv::VecEnv(const Scenario* scenario, int num_envs, uint64_t seed)
    : scenario_(scenario),
      num_envs_(num_envs),
      n_(scenario->num_agents()),
      k_(scenario->state_size()),
      states_(static_cast<size_t>(num_envs) * k_),
      episode_count_(num_envs, -1),  // Reseed starts episode 0.
      returns_(num_envs, 0.0f) {
  rngs_.resize(num_envs);
  Reseed(seed);
  finished_.reserve(num_envs * 2);
}

uint64_t VecEnv::EnvSeed(uint64_t seed, int e) {
  uint64_t mix = seed ^ (0x5851f42d4c957f2dULL * (e + 1));
  return Rng::SplitMix64(mix);
}

void VecEnv::Reseed(uint64_t seed, const int32_t* states) {
  for (int e = 0; e < num_envs_; ++e) {
    rngs_[e].Seed(EnvSeed(seed, e));
    int32_t* state = &states_[static_cast<size_t>(e) * k_];
    if (states != nullptr) {
      std::memcpy(state, states + static_cast<size_t>(e) * k_, sizeof(int32_t) * k_);
    } else {
      scenario_->Reset(rngs_[e], state);
    }
    StartEpisode(e);
  }
}

void VecEnv::ResetEnv(int e) {
  scenario_->Reset(rngs_[e], &states_[static_cast<size_t>(e) * k_]);
  StartEpisode(e);
}

void VecEnv::StartEpisode(int e) {
  returns_[e] = 0;
  ++episode_count_[e];
}

void VecEnv::Step(const int32_t* actions, float* rewards, bool* terminated, bool* truncated,
                  int32_t* reached_states) {
  for (int e = 0; e < num_envs_; ++e) {
    int32_t* state = &states_[static_cast<size_t>(e) * k_];
    float* r = rewards + static_cast<size_t>(e) * n_;
    const StepOutcome outcome = scenario_->Step(state, actions + static_cast<size_t>(e) * n_, rngs_[e], r);
    float sum = 0;
    for (int a = 0; a < n_; ++a) sum += r[a];
    returns_[e] += sum / n_;
    terminated[e] = outcome.terminated;
    truncated[e] = outcome.truncated;
    std::memcpy(reached_states + static_cast<size_t>(e) * k_, state, sizeof(int32_t) * k_);
    if (outcome.terminated || outcome.truncated) {
      finished_.push_back({returns_[e], state[scenario_->step_index()], outcome.success, e});
      ResetEnv(e);
    }
  }
}

void VecEnv::TakeFinished(std::vector<EpisodeEnd>* out) {
  out->insert(out->end(), finished_.begin(), finished_.end());
  finished_.clear();
}

}  // namespace imca::env
