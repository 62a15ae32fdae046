#ifndef IMCA_COMMON_VEC_ENV_H_
#define IMCA_COMMON_VEC_ENV_H_

#include <cstdint>
#include <vector>

#include "common/env.h"
#include "common/rng.h"

namespace imca::env {

struct EpisodeEnd {
  float team_return = 0;  // Sum of rewards over the episode, averaged over agents.
  int32_t length = 0;
  bool success = false;
};

// E environments of one scenario stepped together, auto-resetting. All buffers
// are allocated in the constructor; Step allocates nothing (the finished-episode
// list keeps its capacity between TakeFinished calls). Environment e draws from
// its own Rng seeded from (seed, e), so results do not depend on E's grouping.
// Not thread-safe.
class VecEnv {
 public:
  VecEnv(const Scenario* scenario, int num_envs, uint64_t seed);

  const Scenario& scenario() const { return *scenario_; }
  int num_envs() const { return num_envs_; }
  // Current states, [E][K].
  const int32_t* states() const { return states_.data(); }
  // Episode id of the current episode of env e (unique within this VecEnv).
  int64_t episode_id(int e) const { return episode_count_[e] * num_envs_ + e; }

  // Steps env e with actions[e*n .. e*n+n) for every e. Writes rewards [E][n],
  // terminated and truncated [E] and the reached states [E][K] (before any
  // reset); then resets every env whose episode ended.
  void Step(const int32_t* actions, float* rewards, bool* terminated, bool* truncated,
            int32_t* reached_states);

  // Moves the episodes finished since the last call into `out` (appending).
  void TakeFinished(std::vector<EpisodeEnd>* out);

 private:
  const Scenario* scenario_;
  int num_envs_;
  int n_;
  int k_;
  std::vector<Rng> rngs_;
  std::vector<int32_t> states_;
  std::vector<int64_t> episode_count_;
  std::vector<float> returns_;
  std::vector<EpisodeEnd> finished_;
};

}  // namespace imca::env

#endif  // IMCA_COMMON_VEC_ENV_H_
