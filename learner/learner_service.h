#ifndef IMCA_LEARNER_LEARNER_SERVICE_H_
#define IMCA_LEARNER_LEARNER_SERVICE_H_

#include "common/metrics/metrics.h"
#include "common/rpc/admission.h"
#include "imca/v1/learner_service.grpc.pb.h"
#include "learner/learner.h"

namespace imca::learner {

// The ack of a push that Learner::Push answered with `outcome`: accepted, or
// the typed rejection the actor acts on, with the message; and the
// learner's current version.
v1::PushUnrollsResponse AckOf(const PushOutcome& outcome, int64_t policy_version);

// The gRPC face of a Learner (sync API: each PushUnrolls stream holds one
// server thread, which is what gives back-pressure). At most `max_streams`
// PushUnrolls streams, and as many GetPolicy long polls (wait_ms > 0), are
// served at once; one more ends at once with RESOURCE_EXHAUSTED (an actor
// retries it with backoff), so a client that opens calls in a loop cannot
// take every thread. Each stream's first
// unroll logs its actor id and the peer's identity (docs/security.md).
// Thread-safe.
class LearnerServiceImpl final : public v1::LearnerService::Service {
 public:
  static constexpr int kDefaultMaxStreams = 256;

  explicit LearnerServiceImpl(Learner* learner, int max_streams = kDefaultMaxStreams);

  using PushStream = grpc::ServerReaderWriterInterface<v1::PushUnrollsResponse, v1::PushUnrollsRequest>;

  grpc::Status PushUnrolls(
      grpc::ServerContext* context,
      grpc::ServerReaderWriter<v1::PushUnrollsResponse, v1::PushUnrollsRequest>* stream) override;
  // PushUnrolls over any stream (the seam of Reverb's InsertStreamInternal):
  // one ack per unroll read, in order, until the stream or the learner ends.
  // Tests feed it a stream that fails on cue instead of copying this loop.
  grpc::Status PushUnrollsInternal(grpc::ServerContext* context, PushStream* stream);
  grpc::Status GetPolicy(grpc::ServerContext* context, const v1::GetPolicyRequest* request,
                         v1::Policy* response) override;
  grpc::Status GetStatus(grpc::ServerContext* context, const v1::GetStatusRequest* request,
                         v1::LearnerStatus* response) override;

  // The service's Prometheus families: unroll streams open (the actors
  // connected) and GetPolicy calls waiting.
  const metrics::Registry& metrics() const { return registry_; }

 private:
  Learner* learner_;
  const int max_streams_;
  ConcurrencyLimiter streams_;  // PushUnrolls streams.
  ConcurrencyLimiter waiters_;  // GetPolicy calls that wait.
  metrics::Registry registry_;
  metrics::Gauge& open_streams_;
  metrics::Gauge& waiting_polls_;
};

}  // namespace imca::learner

#endif  // IMCA_LEARNER_LEARNER_SERVICE_H_
