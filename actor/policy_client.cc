#include "actor/policy_client.h"

#include <algorithm>
#include <cstdio>
#include <utility>

#include "absl/strings/str_cat.h"
#include "common/rpc/grpc_util.h"
#include "common/rpc/transport.h"

namespace imca::actor {

PolicyClient::PolicyClient(v1::LearnerService::StubInterface* learner, const env::Scenario& scenario,
                           const PolicyClientOptions& options, StopSignal* stop, Admit admit, OnWait on_wait)
    : learner_(learner),
      scenario_(scenario),
      options_(options),
      stop_(stop),
      admit_(std::move(admit)),
      on_wait_(std::move(on_wait)) {}

bool PolicyClient::Refresh(bool wait) {
  return Fetch(policy_.has_value() ? policy_->version() + 1 : 0, /*retry=*/wait, /*until_newer=*/false);
}

bool PolicyClient::Await(int64_t min_version) { return Fetch(min_version, /*retry=*/true, /*until_newer=*/true); }

bool PolicyClient::Restart() {
  policy_.reset();
  return Refresh(/*wait=*/true);
}

bool PolicyClient::Fetch(int64_t min_version, bool retry, bool until_newer) {
  // A long poll waits on the learner for at most half the deadline.
  const int wait_ms =
      until_newer ? static_cast<int>(std::clamp<int64_t>(options_.rpc_timeout.count() / 2, 1, 5000)) : 0;
  Backoff backoff;
  while (!stop_->stopped()) {
    if (on_wait_) on_wait_();
    grpc::ClientContext context;
    context.set_deadline(DeadlineIn(options_.rpc_timeout));
    v1::GetPolicyRequest request;
    request.set_min_version(min_version);
    request.set_wait_ms(wait_ms);
    v1::Policy policy;
    grpc::Status status;
    {
      const StopSignal::Call call(stop_, &context);
      status = learner_->GetPolicy(&context, request, &policy);
    }
    if (!status.ok()) {
      if (stop_->stopped()) return false;  // Cancelled by the stop.
      const absl::Status failed = FromGrpcStatus(status);
      if (IsRefusal(failed)) {
        error_ = absl::Status(failed.code(), DescribeRpcFailure("learner", failed, options_.tls));
        return false;
      }
      // Said once, then every 10 s: a wrong certificate must not look like
      // a learner that is still starting.
      if (const auto now = std::chrono::steady_clock::now(); now - failure_logged_ > std::chrono::seconds(10)) {
        failure_logged_ = now;
        std::fprintf(stderr, "%s: GetPolicy: %s; retrying\n", options_.actor_id.c_str(),
                     DescribeRpcFailure("learner", failed, options_.tls).c_str());
      }
      if (!retry || (until_newer && LearnerDone())) return false;
      backoff.Wait([this] { return stop_->stopped(); });
      continue;
    }
    backoff.Reset();
    // A policy, not a "not modified" answer (a bare version).
    if (policy.tensors_size() > 0 || policy.has_tabular()) return Adopt(policy);
    if (policy_.has_value() &&
        (policy.version() < policy_->version() || policy.learner_incarnation() != learner_incarnation_)) {
      // Not modified, but the learner restarted from a checkpoint: older
      // than ours, or ours, without the unrolls of it the old one took.
      // Take whatever it has, and deliver that version's share anew.
      policy_.reset();
      min_version = 0;
      continue;
    }
    if (!until_newer) return policy_.has_value();  // Nothing newer: keep acting with ours.
    if (LearnerDone()) return false;
  }
  return false;
}

bool PolicyClient::Adopt(const v1::Policy& policy) {
  absl::StatusOr<ActingPolicy> acting = ActingPolicy::FromProto(policy, scenario_);
  if (!acting.ok()) {
    error_ = absl::InternalError(
        absl::StrCat("learner's policy does not fit ", scenario_.name(), ": ", acting.status().message()));
    return false;
  }
  if (admit_) {
    if (absl::Status admitted = admit_(policy); !admitted.ok()) {
      error_ = std::move(admitted);
      return false;
    }
  }
  policy_.emplace(*std::move(acting));
  learner_incarnation_ = policy.learner_incarnation();
  return true;
}

bool PolicyClient::LearnerDone() {
  grpc::ClientContext context;
  context.set_deadline(DeadlineIn(std::chrono::seconds(2)));
  v1::LearnerStatus status;
  const StopSignal::Call call(stop_, &context);
  return learner_->GetStatus(&context, v1::GetStatusRequest(), &status).ok() && status.done();
}

}  // namespace imca::actor
