#ifndef IMCA_COMMON_ENV_VEC_ENV_H_
#define IMCA_COMMON_ENV_VEC_ENV_H_

#include <cstdint>
#include <vector>

#include "common/base/rng.h"
#include "common/env/env.h"

namespace imca::env {

struct EpisodeEnd {
  float team_return = 0;  // Sum of rewards over the episode, averaged over agents.
  int32_t length = 0;
  bool success = false;
  int32_t env = 0;  // Which environment of the VecEnv played it.
};

// E environments of one scenario stepped together, auto-resetting. All buffers
// are allocated in the constructor; Step allocates nothing (the finished-episode
// list keeps its capacity between TakeFinished calls). Environment e draws from
// its own Rng(EnvSeed(seed, e)), so results do not depend on E's grouping.
// Not thread-safe.
class VecEnv {
 public:
  VecEnv(const Scenario* scenario, int num_envs, uint64_t seed);

  // The seed of environment e's Rng under `seed`: the same as the env tool's
  // --seed (imca_env plays env e of a VecEnv given this value).
  static uint64_t EnvSeed(uint64_t seed, int e);

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

  // Starts a new episode in every env with its Rng reseeded from
  // EnvSeed(seed, e), as the constructor does: from a Reset draw or, if
  // `states` ([E][K], each passing Scenario::ValidateState; the caller
  // checks) is given, from those states with nothing drawn. Episode ids
  // continue; unfinished episodes are dropped, not reported.
  void Reseed(uint64_t seed, const int32_t* states = nullptr);
  // Starts a new episode in env e from a Reset draw of its Rng as it stands.
  void ResetEnv(int e);

 private:
  // A new episode id and a zero return for env e.
  void StartEpisode(int e);

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

#endif  // IMCA_COMMON_ENV_VEC_ENV_H_
