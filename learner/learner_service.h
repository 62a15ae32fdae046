#ifndef IMCA_LEARNER_LEARNER_SERVICE_H_
#define IMCA_LEARNER_LEARNER_SERVICE_H_

#include "imca/v1/learner_service.grpc.pb.h"
#include "learner/learner.h"

namespace imca::learner {

// The ack of a push that Learner::Push answered with `status`: accepted, or
// the typed rejection (one per refusal code, learner.h) the actor acts on,
// with the message; and the learner's current version.
v1::PushUnrollsResponse AckOf(const absl::Status& status, int64_t policy_version);

// The gRPC face of a Learner (sync API: each PushUnrolls stream holds one
// server thread, which is what gives back-pressure). Thread-safe.
class LearnerServiceImpl final : public v1::LearnerService::Service {
 public:
  explicit LearnerServiceImpl(Learner* learner) : learner_(learner) {}

  grpc::Status PushUnrolls(
      grpc::ServerContext* context,
      grpc::ServerReaderWriter<v1::PushUnrollsResponse, v1::PushUnrollsRequest>* stream) override;
  grpc::Status GetPolicy(grpc::ServerContext* context, const v1::GetPolicyRequest* request,
                         v1::Policy* response) override;
  grpc::Status GetStatus(grpc::ServerContext* context, const v1::GetStatusRequest* request,
                         v1::LearnerStatus* response) override;

 private:
  Learner* learner_;
};

}  // namespace imca::learner

#endif  // IMCA_LEARNER_LEARNER_SERVICE_H_
