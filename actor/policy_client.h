#ifndef IMCA_ACTOR_POLICY_CLIENT_H_
#define IMCA_ACTOR_POLICY_CLIENT_H_

#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "absl/status/status.h"
#include "actor/stop_signal.h"
#include "common/env/env.h"
#include "common/protocol/acting_policy.h"
#include "imca/v1/learner_service.grpc.pb.h"

namespace imca::actor {

struct PolicyClientOptions {
  std::string actor_id = "actor-0";  // In log lines.
  std::chrono::milliseconds rpc_timeout{10000};
  bool tls = false;  // A failure that reads as a failed handshake is logged as one.
};

// The actor's side of the learner's GetPolicy: fetches the newest policy
// (long-polling when it waits for a newer version) and holds the newest one
// that fits the scenario. Follows a learner that went back (restarted from an
// older checkpoint, or anew at the version held: a new learner incarnation)
// by taking whatever that learner has. Failed calls are retried with
// exponential backoff where the caller asks to wait; a refusal (credentials)
// is not retried. Not thread-safe: one thread calls everything; the
// StopSignal may be set from any thread and ends every wait.
class PolicyClient {
 public:
  // Asked about each policy that fits the scenario before it is taken: an
  // error leaves the policy held as it was and becomes error() (the actor's
  // check of the synchronous share it asks for).
  using Admit = std::function<absl::Status(const v1::Policy&)>;
  // Called before each attempt that may wait (the actor's status file).
  using OnWait = std::function<void()>;

  // `learner` and `stop` must outlive the client.
  PolicyClient(v1::LearnerService::StubInterface* learner, const env::Scenario& scenario,
               const PolicyClientOptions& options, StopSignal* stop, Admit admit, OnWait on_wait);

  // Takes a newer policy than the one held if the learner has one (any
  // policy if none is held). With `wait`, failed calls are retried until one
  // is answered. False if no policy is held afterwards, or on a failure
  // without `wait`, or once error() is set.
  bool Refresh(bool wait);
  // Blocks, long-polling, until the learner publishes version >= min_version
  // (or went back: then its policy is taken). False on stop, once the
  // learner reports its budget done, or once error() is set.
  bool Await(int64_t min_version);
  // Drops the policy held (the learner no longer has its version: an unroll
  // was refused as ahead of it) and waits for the learner's.
  bool Restart();
  // The learner's GetStatus says its budget is done (2 s deadline; false on
  // any failure).
  bool LearnerDone();

  // The policy acted with (a network or CMAE's Q-tables); nullptr before
  // the first one, or after Restart() found none.
  // Not const: evaluating a network uses its scratch buffers.
  ActingPolicy* policy() { return policy_.has_value() ? &*policy_ : nullptr; }
  int64_t version() const { return policy_.has_value() ? policy_->version() : -1; }
  // Why no policy can be had: INTERNAL (the learner's policy does not fit the
  // scenario), the Admit error, or the refusal of a call (credentials). OK
  // otherwise.
  const absl::Status& error() const { return error_; }

 private:
  // GetPolicy(min_version), retrying failures if `retry`; with `until_newer`,
  // long-polls until a version >= min_version arrives instead of returning
  // true on "not modified".
  bool Fetch(int64_t min_version, bool retry, bool until_newer);
  // Takes `policy` if it fits and is admitted; else sets error_.
  bool Adopt(const v1::Policy& policy);

  v1::LearnerService::StubInterface* const learner_;
  const env::Scenario& scenario_;
  const PolicyClientOptions options_;
  StopSignal* const stop_;
  const Admit admit_;
  const OnWait on_wait_;
  std::optional<ActingPolicy> policy_;
  uint64_t learner_incarnation_ = 0;  // Of the learner that served policy_.
  absl::Status error_;
  std::chrono::steady_clock::time_point failure_logged_{};
};

}  // namespace imca::actor

#endif  // IMCA_ACTOR_POLICY_CLIENT_H_
