#ifndef IMCA_LEARNER_LEARNER_SERVICE_H_
#define IMCA_LEARNER_LEARNER_SERVICE_H_

#include "imca/v1/learner_service.grpc.pb.h"
#include "learner/learner.h"

namespace imca::learner {

// Learner::Push's refusal codes, one per reason (learner.h), as the
// PushUnrollsResponse.rejection the actor acts on.
v1::Rejection RejectionOf(const absl::Status& status);

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
