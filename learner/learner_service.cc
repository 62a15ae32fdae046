#include "learner/learner_service.h"

#include "common/grpc_util.h"

namespace imca::learner {

grpc::Status LearnerServiceImpl::PushUnrolls(
    grpc::ServerContext* context,
    grpc::ServerReaderWriter<v1::PushUnrollsResponse, v1::PushUnrollsRequest>* stream) {
  v1::PushUnrollsRequest request;
  while (stream->Read(&request)) {
    const absl::Status status = learner_->Push(std::move(*request.mutable_unroll()));
    // Ends the stream: the learner stops, or its budget is done.
    if (absl::IsUnavailable(status) || absl::IsOutOfRange(status)) return ToGrpcStatus(status);
    v1::PushUnrollsResponse ack;
    ack.set_accepted(status.ok());
    if (!status.ok()) ack.set_error(std::string(status.message()));
    ack.set_policy_version(learner_->CurrentPolicy()->version());
    if (!stream->Write(ack)) break;
  }
  return grpc::Status::OK;
}

grpc::Status LearnerServiceImpl::GetPolicy(grpc::ServerContext*, const v1::GetPolicyRequest* request,
                                           v1::Policy* response) {
  std::shared_ptr<const v1::Policy> policy = learner_->CurrentPolicy();
  if (policy->version() >= request->min_version()) {
    *response = *policy;
  } else {
    response->set_version(policy->version());
  }
  return grpc::Status::OK;
}

grpc::Status LearnerServiceImpl::GetStatus(grpc::ServerContext*, const v1::GetStatusRequest*,
                                           v1::LearnerStatus* response) {
  *response = learner_->Status();
  return grpc::Status::OK;
}

}  // namespace imca::learner
