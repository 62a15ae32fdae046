#ifndef IMCA_LEARNER_PUSH_TESTING_H_
#define IMCA_LEARNER_PUSH_TESTING_H_

#include <string>

#include "absl/status/statusor.h"
#include "learner/unroll_queue.h"

namespace imca::learner {

// Tests' reading of a push (Learner::Push, UnrollQueue::Push).

// Accepted: answered, and not refused.
inline bool Accepted(const absl::StatusOr<PushOutcome>& pushed) { return pushed.ok() && pushed->accepted(); }

// The rejection of an answered push (REJECTION_NONE if accepted); -1 if the
// push ended with a status instead (closed, cancelled).
inline int RejectionOf(const absl::StatusOr<PushOutcome>& pushed) { return pushed.ok() ? pushed->rejection : -1; }

// What a refusal says, or the status that ended the push.
inline std::string Why(const absl::StatusOr<PushOutcome>& pushed) {
  return pushed.ok() ? pushed->error : std::string(pushed.status().message());
}

}  // namespace imca::learner

#endif  // IMCA_LEARNER_PUSH_TESTING_H_
