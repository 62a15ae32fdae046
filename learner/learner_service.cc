#include "learner/learner_service.h"

#include <cstdio>

#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "common/protocol/unroll_check.h"
#include "common/rpc/grpc_util.h"
#include "common/rpc/transport.h"

namespace imca::learner {
namespace {

constexpr int kMaxPolicyWaitMs = 60000;

const metrics::Family kOpenStreams{"imca_learner_unroll_streams", metrics::Type::kGauge,
                                   "PushUnrolls streams open: the actors connected."};
const metrics::Family kWaitingPolls{"imca_learner_policy_polls_waiting", metrics::Type::kGauge,
                                    "GetPolicy calls waiting for a newer policy version."};

// Adds 1 to `gauge` for its lifetime.
class GaugeHold {
 public:
  explicit GaugeHold(metrics::Gauge& gauge) : gauge_(gauge) { gauge_.Add(1); }
  ~GaugeHold() { gauge_.Add(-1); }

 private:
  metrics::Gauge& gauge_;
};

}  // namespace

LearnerServiceImpl::LearnerServiceImpl(Learner* learner, int max_streams)
    : learner_(learner),
      max_streams_(max_streams),
      streams_(max_streams),
      waiters_(max_streams),
      open_streams_(registry_.AddGauge(kOpenStreams)),
      waiting_polls_(registry_.AddGauge(kWaitingPolls)) {}

v1::PushUnrollsResponse AckOf(const PushOutcome& outcome, int64_t policy_version) {
  v1::PushUnrollsResponse ack;
  ack.set_accepted(outcome.accepted());
  ack.set_rejection(outcome.rejection);
  ack.set_error(outcome.error);
  ack.set_policy_version(policy_version);
  return ack;
}

grpc::Status LearnerServiceImpl::PushUnrolls(
    grpc::ServerContext* context,
    grpc::ServerReaderWriter<v1::PushUnrollsResponse, v1::PushUnrollsRequest>* stream) {
  return PushUnrollsInternal(context, stream);
}

grpc::Status LearnerServiceImpl::PushUnrollsInternal(grpc::ServerContext* context, PushStream* stream) {
  absl::StatusOr<ConcurrencyLimiter::Slot> slot = streams_.Acquire();
  if (!slot.ok()) {
    return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                        absl::StrCat("the learner serves at most ", max_streams_, " unroll streams at once (--max_streams)"));
  }
  const GaugeHold open(open_streams_);
  v1::PushUnrollsRequest request;
  bool first = true;
  while (stream->Read(&request)) {
    if (first) {
      first = false;
      std::fprintf(stderr, "learner: unroll stream from %s (%s)\n",
                   absl::CHexEscape(request.unroll().actor_id().substr(0, kMaxActorIdBytes)).c_str(),
                   PeerIdentity(*context).c_str());
    }
    const absl::StatusOr<PushOutcome> outcome =
        learner_->Push(std::move(*request.mutable_unroll()), [context] { return context->IsCancelled(); });
    // Ends the stream: the learner stops, or its budget is done, or the actor left.
    if (!outcome.ok()) return ToGrpcStatus(outcome.status());
    if (!stream->Write(AckOf(*outcome, learner_->CurrentPolicy()->version()))) break;
  }
  return grpc::Status::OK;
}

grpc::Status LearnerServiceImpl::GetPolicy(grpc::ServerContext*, const v1::GetPolicyRequest* request,
                                           v1::Policy* response) {
  if (request->wait_ms() < 0 || request->wait_ms() > kMaxPolicyWaitMs) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                        absl::StrCat("wait_ms: ", request->wait_ms(), " not in [0, ", kMaxPolicyWaitMs, "]"));
  }
  std::shared_ptr<const v1::Policy> policy = learner_->CurrentPolicy();
  if (request->wait_ms() > 0 && policy->version() < request->min_version()) {
    absl::StatusOr<ConcurrencyLimiter::Slot> slot = waiters_.Acquire();
    if (!slot.ok()) {
      return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                          absl::StrCat("the learner holds at most ", max_streams_,
                                       " waiting GetPolicy calls at once (--max_streams)"));
    }
    const GaugeHold waiting(waiting_polls_);
    policy = learner_->WaitForPolicy(request->min_version(), absl::Milliseconds(request->wait_ms()));
  }
  if (policy->version() >= request->min_version()) {
    *response = *policy;
  } else {
    response->set_version(policy->version());
  }
  response->set_learner_incarnation(learner_->incarnation());
  return grpc::Status::OK;
}

grpc::Status LearnerServiceImpl::GetStatus(grpc::ServerContext*, const v1::GetStatusRequest*,
                                           v1::LearnerStatus* response) {
  *response = learner_->Status();
  return grpc::Status::OK;
}

}  // namespace imca::learner
