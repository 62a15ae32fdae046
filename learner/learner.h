#ifndef IMCA_LEARNER_LEARNER_H_
#define IMCA_LEARNER_LEARNER_H_

#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"
#include "absl/time/time.h"
#include "common/base/rng.h"
#include "common/env/env.h"
#include "common/env/featurizer.h"
#include "common/metrics/metrics.h"
#include "imca/v1/learner_service.pb.h"
#include "imca/v1/unroll.pb.h"
#include "learner/algorithms/interface.h"
#include "learner/checkpoint_store.h"
#include "learner/csv_log.h"
#include "learner/iteration_metrics.h"
#include "learner/learner_config.h"
#include "learner/unroll_queue.h"

namespace imca::learner {

// The learner's domain logic, independent of gRPC. It coordinates its parts:
// the UnrollQueue (admission, exactly-once, back-pressure), its Algorithm
// (a registered one, learner/algorithms/registry.h), the CheckpointStore and two CsvLogs
// (metrics.csv, trained_unrolls.csv); it owns the iteration loop, versioned
// policy publication, status and metrics. An iteration hands batch_steps
// joint env steps of unrolls to the algorithm, one at a time as they arrive,
// then trains and publishes. Thread-safe: Push/CurrentPolicy/Status may be
// called from any thread while one thread runs Run().
class Learner {
 public:
  // `scenario` must outlive the learner. Errors: INVALID_ARGUMENT for a bad
  // config; INTERNAL if the run directory cannot be prepared.
  static absl::StatusOr<std::unique_ptr<Learner>> Create(const env::Scenario* scenario,
                                                         const LearnerConfig& config);

  // Validates `unroll`, featurises it on the calling thread and queues it for
  // training; blocks while the queue is full (back-pressure). Returns the
  // outcome the ack carries: accepted (queued), or refused, each reason
  // counted (imca_learner_unrolls_dropped_total):
  //   REJECTION_INVALID: it fails validation (the error names the field);
  //   REJECTION_OVER_CAP: a batch with it would exceed max_batch_bytes, or
  //     its actor id would be one past max_actor_ids;
  //   REJECTION_STALE: more than max_policy_lag versions old, or
  //     (synchronous) not of the current version or beyond its full batch;
  //   REJECTION_AHEAD: its version is newer than the learner's, a learner
  //     resumed from an older checkpoint; refetch the policy;
  //   REJECTION_DUPLICATE: its (actor_id, incarnation, sequence) is not newer
  //     than that actor incarnation's last accepted unroll, a resend.
  // Errors, which end the stream: OUT_OF_RANGE once the budget is done;
  // UNAVAILABLE once the learner is stopping for another reason; CANCELLED
  // if `cancelled` (polled every second while the queue is full) returns
  // true: the pusher went away, nothing was queued.
  absl::StatusOr<PushOutcome> Push(v1::Unroll unroll, const std::function<bool()>& cancelled = nullptr);

  // The newest published policy (never null after Create).
  std::shared_ptr<const v1::Policy> CurrentPolicy() const;
  // This learner's incarnation, drawn at construction (Policy.learner_incarnation).
  uint64_t incarnation() const { return incarnation_; }
  // Blocks until a policy of version >= min_version is published, `timeout`
  // passes or the learner stops; returns the newest policy either way.
  std::shared_ptr<const v1::Policy> WaitForPolicy(int64_t min_version, absl::Duration timeout) const;
  v1::LearnerStatus Status() const;

  // Trains until the budget is reached or Stop() is called, then writes a
  // final checkpoint. Blocks. Errors: INTERNAL from training or I/O.
  absl::Status Run();
  // Makes Run() return after its current iteration and Push() fail. Non-blocking.
  void Stop();

  // Bytes an iteration of `steps` joint env steps needs for its features
  // (Algorithm::IterationBytes).
  int64_t IterationBytes(int64_t steps) const;
  // The algorithm (tests).
  const Algorithm& algorithm() const { return *algorithm_; }
  // The learner's Prometheus families (docs/metrics.md): its metrics.csv
  // columns (iteration_metrics.h), queue, refusals by reason, policy lag.
  const metrics::Registry& metrics() const { return registry_; }

  // Restores trainer, version and counters from a checkpoint directory's
  // newest complete checkpoint, or, if that one cannot be read, from the
  // newest older one that can (CheckpointStore::Restore). Call before Run().
  // Errors: NOT_FOUND (none), or the newest checkpoint's error if none loads
  // (INVALID_ARGUMENT: it does not fit this configuration; INTERNAL).
  absl::Status Restore(const std::string& checkpoint_dir);
  // Writes a checkpoint now (from the training thread only), and the current
  // policy as <run_dir>/policy.pb (a serialized imca.v1.Policy).
  absl::Status SaveCheckpoint();

 private:
  Learner(const env::Scenario* scenario, const LearnerConfig& config, std::unique_ptr<Algorithm> algorithm);

  // Registers the learner's families in registry_ (from the constructor).
  void RegisterMetrics();
  // Push's checks before admission: the unroll's fields, and the memory a
  // batch with it needs (UnrollQueue::Options::validate).
  PushOutcome Validate(const v1::Unroll& unroll) const;
  // Adds an accepted unroll's episodes to the windows (UnrollQueue's on_accept).
  void CountEpisodes(const v1::Unroll& unroll);
  // The queue's next fresh unroll (counting the stale ones it drops);
  // nullopt once stopping.
  std::optional<FeaturisedUnroll> NextUnroll();
  // LearnerStatus's seconds_stalled and seconds_training at `now`.
  double SecondsStalled(std::chrono::steady_clock::time_point now, int queue_depth) const
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  double SecondsTraining(std::chrono::steady_clock::time_point now) const ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  // Adds one unroll to the algorithm's batch (which may train: off-policy).
  absl::Status AddToBatch(FeaturisedUnroll* queued);
  // Trains the algorithm on the iteration made of `unrolls` (already
  // added), publishes and writes metrics.
  absl::Status TrainOn(const std::vector<v1::Unroll>& unrolls);
  void Publish();
  // The algorithm's current weights as policy version_, with the
  // collection contract (Policy.sync_steps_per_actor).
  std::shared_ptr<const v1::Policy> ExportPolicy() const ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  // Means over one batch of the reward server's credit diagnostics.
  struct CreditStats {
    double intrinsic = 0;         // r_i^a per agent-step.
    double share_max = 0;         // max_a p^a per transition.
    double global_reward = 0;     // R_i per transition.
    double contribution_abs = 0;  // |r^a| (or d^a) per agent-step.
    std::vector<double> shares;   // p^a per agent slot.
  };
  CreditStats MeasureCredit(const std::vector<v1::Unroll>& unrolls, int64_t agent_steps) const;
  // The iteration's metrics.csv row.
  IterationRecord Record(const IterationStats& stats, double lag, const CreditStats& credit) const;
  // Appends `row` to `log`, reporting a failure once per run of failures:
  // a log that cannot be written does not stop training (the checkpoints
  // still hold it all).
  static void AppendRow(CsvLog* log, absl::string_view row);

  const env::Scenario* scenario_;
  const LearnerConfig config_;
  // Before everything that registers into it; callbacks read the fields
  // below under mu_.
  metrics::Registry registry_;
  IterationExporter exporter_{&registry_, config_.algo};
  metrics::Histogram* policy_lag_ = nullptr;  // Of each trained unroll, in versions.
  // Refused unrolls by reason (v1::Rejection), each series there from the start.
  std::vector<metrics::Counter*> dropped_;
  std::unique_ptr<Algorithm> algorithm_;  // Training thread only (but its thread-safe Featurise).
  const uint64_t incarnation_ = RandomIncarnation();
  const std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  // <run_dir>/checkpoints, <run_dir>/metrics.csv and config_.trained_log,
  // where set (training thread only).
  std::optional<CheckpointStore> checkpoints_;
  std::optional<CsvLog> metrics_log_;
  std::optional<CsvLog> trained_log_;
  // When the last checkpoint was written (training thread only).
  std::chrono::steady_clock::time_point last_checkpoint_ = std::chrono::steady_clock::now();
  int64_t iteration_ = 0;                // Training thread only.
  // Wall seconds of the current iteration's phases outside the algorithm
  // (training thread only): waiting for unrolls, featurising the batch's
  // unrolls (on the pushing threads, off this one's path), publishing.
  struct Phases {
    double wait = 0, featurise = 0, publish = 0;
  };
  Phases phases_;                        // Training thread only.

  // Admission and the queue of unrolls, with its own lock: never taken
  // while holding the queue's, mu_ may be held while calling it.
  UnrollQueue queue_;

  mutable absl::Mutex mu_;
  double wall_offset_ ABSL_GUARDED_BY(mu_) = 0;  // Seconds of earlier runs (resume).
  bool stopping_ ABSL_GUARDED_BY(mu_) = false;
  std::shared_ptr<const v1::Policy> policy_ ABSL_GUARDED_BY(mu_);
  int64_t version_ ABSL_GUARDED_BY(mu_) = 0;
  int64_t env_steps_ ABSL_GUARDED_BY(mu_) = 0;
  int64_t batches_dropped_ ABSL_GUARDED_BY(mu_) = 0;
  // The training thread's last dequeue or publication.
  std::chrono::steady_clock::time_point last_progress_ ABSL_GUARDED_BY(mu_) = std::chrono::steady_clock::now();
  // Set while the algorithm adds an unroll (which may train) or trains.
  std::optional<std::chrono::steady_clock::time_point> training_since_ ABSL_GUARDED_BY(mu_);
  int64_t minibatches_skipped_ ABSL_GUARDED_BY(mu_) = 0;
  bool done_ ABSL_GUARDED_BY(mu_) = false;
  // The episodes of accepted unrolls, over the last metrics_window: updated
  // under the queue's lock as it accepts (before the training thread can
  // take the unroll), so their own lock, taken last, calling nothing.
  mutable absl::Mutex windows_mu_;
  std::deque<bool> eval_success_ ABSL_GUARDED_BY(windows_mu_);
  std::deque<bool> train_success_ ABSL_GUARDED_BY(windows_mu_);
  std::deque<float> train_returns_ ABSL_GUARDED_BY(windows_mu_);
  double last_intrinsic_ ABSL_GUARDED_BY(mu_) = 0;
};

}  // namespace imca::learner

#endif  // IMCA_LEARNER_LEARNER_H_
