// Fuzzes the learner service's GetPolicy (and GetStatus) in-process: bytes
// -> a parsed GetPolicyRequest -> LearnerServiceImpl::GetPolicy. A request
// that would only wait (a valid wait_ms for a version the learner does not
// have yet) is not run: it waits by design. Invariants: an answer never
// claims a version the learner does not have, and carries the weights
// exactly when the learner's version reaches min_version.
#include <cstdint>
#include <memory>

#include "fuzz/fuzz_check.h"
#include "fuzz/fuzz_learner.h"
#include "google/protobuf/stubs/logging.h"
#include "imca/v1/learner_service.pb.h"
#include "learner/learner.h"
#include "learner/learner_service.h"

using namespace imca;

namespace {
learner::Learner* trainer = nullptr;
learner::LearnerServiceImpl* service = nullptr;
}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  // Mutated strings are often not UTF-8: protobuf would log each one.
  google::protobuf::SetLogHandler(nullptr);
  trainer = fuzz::FuzzLearner();
  service = new learner::LearnerServiceImpl(trainer);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  grpc::ServerContext context;
  const int64_t version = trainer->CurrentPolicy()->version();
  if (data[0] % 2 == 1) {
    v1::GetStatusRequest request;
    if (!request.ParseFromArray(data + 1, static_cast<int>(size - 1))) return 0;
    v1::LearnerStatus status;
    FUZZ_CHECK(service->GetStatus(&context, &request, &status).ok());
    FUZZ_CHECK(status.policy_version() == version);
    return 0;
  }
  v1::GetPolicyRequest request;
  if (!request.ParseFromArray(data + 1, static_cast<int>(size - 1))) return 0;
  if (request.wait_ms() > 0 && request.wait_ms() <= 60000 && request.min_version() > version) return 0;
  v1::Policy policy;
  const grpc::Status status = service->GetPolicy(&context, &request, &policy);
  if (!status.ok()) {
    FUZZ_CHECK(status.error_code() == grpc::StatusCode::INVALID_ARGUMENT);
    return 0;
  }
  FUZZ_CHECK(policy.version() == version);
  FUZZ_CHECK((policy.tensors_size() > 0) == (request.min_version() <= version));
  return 0;
}
