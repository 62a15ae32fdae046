#ifndef IMCA_COMMON_FEATURIZER_H_
#define IMCA_COMMON_FEATURIZER_H_

#include <cstdint>

#include "common/env.h"

namespace imca::env {

// The one encoder from compact states to network inputs, used by every
// process so that all featurise identically (see docs/observations.md).
//
// Observation of agent a (policy input), obs_dim floats:
//   [row one-hot H | col one-hot W] for agent a, then for agents a+1, ...,
//   a+n-1 (mod n) in that order; object bits (num_object_bits);
//   agent-id one-hot (n); t / step_limit.
// Global state (critic input), global_dim floats:
//   [row one-hot | col one-hot] for agents 0..n-1; object bits; t / step_limit.
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
  float* PutAgent(int32_t cell, float* out) const;
  float* PutTail(const int32_t* state, float* out) const;

  const Scenario& scenario_;
  int n_;
  int width_;
  int height_;
  int object_bits_;
  int obs_dim_;
  int global_dim_;
};

}  // namespace imca::env

#endif  // IMCA_COMMON_FEATURIZER_H_
