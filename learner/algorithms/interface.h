#ifndef IMCA_LEARNER_ALGORITHMS_INTERFACE_H_
#define IMCA_LEARNER_ALGORITHMS_INTERFACE_H_

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "imca/v1/learner_service.pb.h"
#include "imca/v1/unroll.pb.h"

namespace imca::learner {

// The learner's training algorithm, behind which the service, the queue,
// policy versions, checkpoints' metadata and metrics are shared
// (learner/learner.h). Each implementation is a folder beside this file,
// registered in registry.cc: an on-policy one trains on an iteration's
// unrolls as one batch; an off-policy one (off_policy()) learns as it adds,
// from a replay of any age. Torch stays behind the implementations' .cc
// files.

// A validated unroll with the network inputs its algorithm computed on the
// pushing thread (the training thread then only trains).
struct FeaturisedUnroll {
  v1::Unroll unroll;
  std::vector<float> obs;            // Algorithm-specific layouts (see each).
  std::vector<float> critic_inputs;
  double featurise_seconds = 0;
};

// What one iteration did. The fields below are every algorithm's (in its
// own sense, documented by each); `values` holds the algorithm's own
// columns of metrics.csv by name, exactly those the metrics table lists for
// it (its registry entry's columns, learner/algorithms/registry.h).
struct IterationStats {
  std::vector<std::pair<std::string, double>> values;
  double entropy = 0;    // Of the acting policies, nats.
  double grad_norm = 0;  // Before clipping, mean over gradient steps.
  // Gradient steps not taken because their loss or gradient was not finite,
  // and why the first of them failed.
  int64_t minibatches_skipped = 0;
  std::string skip_reason;
  int64_t updates = 0;  // Gradient steps taken (PPO: minibatch steps).
  // Wall seconds of adding the iteration's unrolls: values, GAE and copying
  // for PPO; MADDPG's inserting counts as copy (its due updates as Train's
  // forward, backward and optimizer phases).
  double seconds_values = 0, seconds_gae = 0, seconds_copy = 0;
  // Of training: the batch made ready, then summed over gradient steps the
  // forward passes and losses, backward passes, clipping and optimiser steps.
  double seconds_prepare = 0, seconds_forward = 0, seconds_backward = 0, seconds_optimizer = 0;
};

// Not thread-safe except where noted: the learner's training thread owns it.
class Algorithm {
 public:
  virtual ~Algorithm() = default;

  // Thread-safe, called on the pushing threads: the unroll's network inputs.
  virtual FeaturisedUnroll Featurise(v1::Unroll unroll) const = 0;
  // Thread-safe: bytes an iteration of `steps` joint env steps holds in
  // features (the learner's memory cap, --max_batch_mb).
  virtual int64_t IterationBytes(int64_t steps) const = 0;

  // Off-policy: learns from unrolls of any policy version (the learner
  // drops none as stale), and trains as it adds (so an iteration cut short
  // by a stop has trained and is counted and published).
  virtual bool off_policy() const { return false; }
  // Thread-safe: the unrolls must carry influences (the learner refuses
  // others, INVALID_ARGUMENT naming unroll.influences).
  virtual bool needs_influences() const { return false; }

  // Takes one unroll of the current iteration. Errors: INTERNAL (torch).
  virtual absl::Status Add(const FeaturisedUnroll& unroll) = 0;
  // Ends the iteration and returns what it did. Errors, each leaving the
  // weights as they were: INVALID_ARGUMENT, a batch the algorithm refuses
  // (the learner drops it and publishes the same weights again); INTERNAL.
  virtual absl::StatusOr<IterationStats> Train() = 0;

  // The acting policy, as the actors load it (learner_service.proto).
  virtual v1::Policy ExportPolicy(int64_t version) const = 0;
  // The algorithm's whole state. Errors: INTERNAL on I/O; Load:
  // INVALID_ARGUMENT if the file does not fit this configuration (nothing
  // changed).
  virtual absl::Status Save(const std::string& path) const = 0;
  virtual absl::Status Load(const std::string& path) = 0;
};

}  // namespace imca::learner

#endif  // IMCA_LEARNER_ALGORITHMS_INTERFACE_H_
