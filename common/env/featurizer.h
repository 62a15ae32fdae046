#ifndef IMCA_COMMON_ENV_FEATURIZER_H_
#define IMCA_COMMON_ENV_FEATURIZER_H_

#include <cstdint>

#include "common/env/env.h"

namespace imca::env {

// The one encoder from compact states to network inputs, used by every
// process so that all featurise identically (docs/scenarios.md).
//
// Observation of agent a (policy input), obs_dim floats:
//   [row one-hot H | col one-hot W] for agent a, then for agents a+1, ...,
//   a+n-1 (mod n) in that order, then for each non-player entity (the prey);
//   object bits (num_object_bits); agent-id one-hot (n); t / step_limit.
//   With a view radius r > 0, another agent or entity farther than r cells
//   (Chebyshev distance) from agent a is encoded as all zeros.
// Global state (critic input), global_dim floats:
//   [row one-hot | col one-hot] for agents 0..n-1 and the entities; object
//   bits; t / step_limit. (Never masked.)
// Immutable; thread-safe.
class Featurizer {
 public:
  explicit Featurizer(const Scenario& scenario);

  int obs_dim() const { return obs_dim_; }
  int global_dim() const { return global_dim_; }

  // Writes obs_dim floats for agent `agent` of `state` into out.
  void Observe(const int32_t* state, int agent, float* out) const;
  // Writes global_dim floats for `state` into out.
  void GlobalState(const int32_t* state, float* out) const;

 private:
  float* PutCell(int32_t cell, bool visible, float* out) const;
  float* PutObjects(const int32_t* state, float* out) const;
  bool Visible(int32_t from, int32_t to) const;

  const Scenario& scenario_;
  int n_;
  int m_;
  int width_;
  int height_;
  int object_bits_;
  int radius_;
  int obs_dim_;
  int global_dim_;
};

}  // namespace imca::env

#endif  // IMCA_COMMON_ENV_FEATURIZER_H_
