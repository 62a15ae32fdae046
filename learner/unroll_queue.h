#ifndef IMCA_LEARNER_UNROLL_QUEUE_H_
#define IMCA_LEARNER_UNROLL_QUEUE_H_

#include <cstdint>
#include <deque>
#include <functional>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/container/flat_hash_map.h"
#include "absl/status/status.h"
#include "absl/synchronization/mutex.h"
#include "absl/status/statusor.h"
#include "imca/v1/learner_service.pb.h"
#include "imca/v1/unroll.pb.h"
#include "learner/algorithms/interface.h"

namespace imca::learner {

// What became of a pushed unroll: accepted (queued), or refused for a reason
// the sender acts on (the ack's v1::Rejection) with a message naming what is
// wrong (an invalid unroll's field and element).
struct PushOutcome {
  v1::Rejection rejection = v1::REJECTION_NONE;  // REJECTION_NONE exactly when accepted.
  std::string error;                             // Empty when accepted.
  bool accepted() const { return rejection == v1::REJECTION_NONE; }
};
inline PushOutcome Refused(v1::Rejection rejection, std::string error) { return {rejection, std::move(error)}; }

// The learner's admission of unrolls, as Reverb's RateLimiter and Table
// split a replay server's: which unroll is taken (validity, policy version,
// staleness, exactly-once per actor incarnation, a cap on actor ids), and a
// bounded queue between the pushing (gRPC) threads and the training thread
// with back-pressure. It knows the current policy version (NewVersion) and
// nothing of training.
//
// Thread-safe: Push from any threads, Next from one (the training thread),
// the rest from any.
class UnrollQueue {
 public:
  struct Options {
    int capacity = 4;             // Unrolls queued at most (then Push blocks).
    bool synchronous = false;     // Only the current version, at most batch_steps of it.
    int64_t batch_steps = 1;
    // Versions an unroll may lag behind (checked at Push and again at Next);
    // nullopt: any (an off-policy algorithm).
    std::optional<int> max_policy_lag = 0;
    int max_actor_ids = 1024;
    // Validates an unroll before anything else: accepted if it is valid,
    // else refused (REJECTION_INVALID naming the field, REJECTION_OVER_CAP
    // over a cap); any thread.
    std::function<PushOutcome(const v1::Unroll&)> validate;
    // Turns an admitted unroll into the training thread's inputs, on the
    // pushing thread and outside the lock; any thread.
    std::function<FeaturisedUnroll(v1::Unroll)> featurise;
    // Called with each accepted unroll under the queue's lock, just before
    // Next can take it (may be empty); must not call the queue.
    std::function<void(const v1::Unroll&)> on_accept;
  };

  // The newest accepted (or trained) unroll of an actor incarnation.
  struct Accepted {
    uint64_t incarnation = 0;
    int64_t sequence = 0;
  };

  // What Status and the metrics read, taken under one lock.
  struct Stats {
    int64_t received = 0;      // Accepted into the queue.
    int64_t stale = 0;         // Refused or dropped as too old.
    int64_t rejected = 0;      // Invalid, ahead, over the id cap.
    int64_t duplicate = 0;     // Resends of accepted unrolls.
    int64_t incarnations = 0;  // Actor incarnations seen.
    int32_t depth = 0;         // Unrolls queued.
    int64_t queued_steps = 0;  // Their joint env steps.
    int32_t pushers_waiting = 0;  // Pushes blocked on a full queue.
    int64_t actor_ids = 0;        // Actor ids seen (ActorIds lists them).
  };

  explicit UnrollQueue(Options options);

  // Validates, admits, featurises (outside the lock) and queues `unroll`;
  // blocks while the queue is full. Returns whether it was accepted (queued)
  // or refused and why (Learner::Push lists the reasons), each counted in
  // Stats. Errors, nothing queued: OUT_OF_RANGE or UNAVAILABLE once closed;
  // CANCELLED if `cancelled`, polled every second while the queue is full,
  // returns true.
  absl::StatusOr<PushOutcome> Push(v1::Unroll unroll, const std::function<bool()>& cancelled = nullptr);

  // Blocks for the next queued unroll that is still fresh enough, dropping
  // (and counting, in `*dropped_stale` too) those that aged past
  // max_policy_lag while queued; nullopt once closed. The training thread.
  std::optional<FeaturisedUnroll> Next(int* dropped_stale);

  // The learner published `version`: unrolls are judged against it, and a
  // synchronous batch starts empty. Non-blocking.
  void NewVersion(int64_t version);
  // Records unrolls as trained: the exactly-once state a checkpoint saves.
  void MarkTrained(const std::vector<v1::Unroll>& unrolls);
  // The newest trained unroll of each actor id.
  absl::flat_hash_map<std::string, Accepted> Trained() const;
  // A restored learner's state: its version, and what it had trained (which
  // resends are duplicates; what was only queued died with the process).
  void Restore(int64_t version, const absl::flat_hash_map<std::string, Accepted>& trained);

  // Refuses further pushes (OUT_OF_RANGE if `budget_done`, else UNAVAILABLE)
  // and wakes every waiter. Non-blocking.
  void Close(bool budget_done);
  Stats stats() const;
  // Every actor id seen, sorted.
  std::vector<std::string> ActorIds() const;

 private:
  // Push's checks of the version, staleness, duplicates and ids: accepted
  // (and, synchronous, its steps counted towards the version's batch) or
  // refused (counted); the closed status once closed.
  absl::StatusOr<PushOutcome> Admit(const v1::Unroll& unroll) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  // REJECTION_DUPLICATE (counted) if `unroll` is not newer than its actor
  // incarnation's last accepted one.
  PushOutcome CheckNotDuplicate(const v1::Unroll& unroll) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  // REJECTION_OVER_CAP (counted) if the unroll's actor id would be one past
  // max_actor_ids.
  PushOutcome CheckActorIdRoom(const v1::Unroll& unroll) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  // Records an accepted unroll's actor, incarnation and sequence.
  void Accept(const v1::Unroll& unroll) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  absl::Status ClosedStatus() const ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  bool TooOld(const v1::Unroll& unroll) const ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);

  const Options options_;

  mutable absl::Mutex mu_;
  bool closed_ ABSL_GUARDED_BY(mu_) = false;
  bool budget_done_ ABSL_GUARDED_BY(mu_) = false;
  int64_t version_ ABSL_GUARDED_BY(mu_) = 0;
  // Synchronous mode: steps admitted for the current version.
  int64_t version_steps_ ABSL_GUARDED_BY(mu_) = 0;
  std::deque<FeaturisedUnroll> queue_ ABSL_GUARDED_BY(mu_);
  Stats stats_ ABSL_GUARDED_BY(mu_);
  // At most options_.max_actor_ids (Push refuses one more).
  std::set<std::string> actors_ ABSL_GUARDED_BY(mu_);
  absl::flat_hash_map<std::string, Accepted> accepted_ ABSL_GUARDED_BY(mu_);
  absl::flat_hash_map<std::string, Accepted> trained_ ABSL_GUARDED_BY(mu_);
};

}  // namespace imca::learner

#endif  // IMCA_LEARNER_UNROLL_QUEUE_H_
