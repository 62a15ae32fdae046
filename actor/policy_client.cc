#include "actor/policy_client.h"

#include <algorithm>
#include <cstdio>
#include <utility>

#include "absl/strings/str_cat.h"
#include "rpc/grpc_util.h"
#include "rpc/transport.h"

namespace imca::actor {

PolicyClient::PolicyClient(v1::LearnerService::StubInterface* learner, const env::Scenario& scenario, int obs_dim,
                           const PolicyClientOptions& options, StopSignal* stop, Admit admit, OnWait on_wait)
    : learner_(learner),
      scenario_(scenario),
      obs_dim_(obs_dim),
      options_(options),
      stop_(stop),
      admit_(std::move(admit)),
      on_wait_(std::move(on_wait)) {}

bool PolicyClient::Refresh(bool wait) {
  return Fetch(held() ? version() + 1 : 0, /*retry=*/wait, /*until_newer=*/false);
}

bool PolicyClient::Await(int64_t min_version) { return Fetch(min_version, /*retry=*/true, /*until_newer=*/true); }

bool PolicyClient::Restart() {
  Drop();
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
    if (held() && (policy.version() < version() || policy.learner_incarnation() != learner_incarnation_)) {
      // Not modified, but the learner restarted from a checkpoint: older
      // than ours, or ours, without the unrolls of it the old one took.
      // Take whatever it has, and deliver that version's share anew.
      Drop();
      min_version = 0;
      continue;
    }
    if (!until_newer) return held();  // Nothing newer: keep acting with ours.
    if (LearnerDone()) return false;
  }
  return false;
}

bool PolicyClient::Adopt(const v1::Policy& policy) {
  std::optional<PolicyMlp> mlp;
  std::optional<PolicyTable> table;
  absl::Status fits;
  if (policy.architecture() == v1::Policy::TABULAR_Q) {
    absl::StatusOr<PolicyTable> read = PolicyTable::FromProto(policy, scenario_);
    fits = read.status();
    if (read.ok()) table = *std::move(read);
  } else {
    absl::StatusOr<PolicyMlp> read = PolicyMlp::FromProto(policy);
    fits = read.ok() ? read->Fits(obs_dim_, scenario_.num_actions(), scenario_.num_agents()) : read.status();
    if (fits.ok()) mlp = *std::move(read);
  }
  if (!fits.ok()) {
    error_ = absl::InternalError(absl::StrCat("learner's policy does not fit ", scenario_.name(), ": ", fits.message()));
    return false;
  }
  if (admit_) {
    if (absl::Status admitted = admit_(policy); !admitted.ok()) {
      error_ = std::move(admitted);
      return false;
    }
  }
  mlp_ = std::move(mlp);
  table_ = std::move(table);
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
