// Fuzzes the learner's request handling in-process: bytes -> a parsed
// PushUnrollsRequest -> Learner::Push (validation, admission, the duplicate
// and staleness checks, featurising, the queue) -> the ack the service
// sends. A learner trains in the background on what is accepted (one small
// PPO iteration per 256 steps), so versions move and stale, ahead and
// duplicate paths are reached. Invariants: an ack matches its status, and a
// refused unroll counts nothing.
#include <cstdint>
#include <cstdlib>
#include <memory>
#include <thread>

#include "fuzz/fuzz_check.h"
#include "fuzz/fuzz_learner.h"
#include "google/protobuf/stubs/logging.h"
#include "imca/v1/learner_service.pb.h"
#include "learner/learner.h"
#include "learner/learner_service.h"

using namespace imca;

namespace {
learner::Learner* trainer = nullptr;
std::thread* training = nullptr;

// At exit, before the libraries' statics are destroyed: stop training.
void StopTraining() {
  trainer->Stop();
  training->join();
}
}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  // Mutated strings are often not UTF-8: protobuf would log each one.
  google::protobuf::SetLogHandler(nullptr);
  trainer = fuzz::FuzzLearner(/*batch_steps=*/256);
  training = new std::thread([] { trainer->Run().IgnoreError(); });
  std::atexit(StopTraining);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  v1::PushUnrollsRequest request;
  if (!request.ParseFromArray(data, static_cast<int>(size))) return 0;
  learner::Learner& l = *trainer;
  const int64_t before = l.Status().unrolls_received();
  const absl::StatusOr<learner::PushOutcome> outcome =
      l.Push(std::move(*request.mutable_unroll()), [] { return false; });
  const int64_t after = l.Status().unrolls_received();
  if (!outcome.ok()) {  // The learner closed (its budget trained): nothing was queued.
    FUZZ_CHECK(after == before);
    return 0;
  }
  FUZZ_CHECK(after == before + (outcome->accepted() ? 1 : 0));
  const v1::PushUnrollsResponse ack = learner::AckOf(*outcome, l.CurrentPolicy()->version());
  FUZZ_CHECK(ack.accepted() == outcome->accepted());
  FUZZ_CHECK((ack.rejection() == v1::REJECTION_NONE) == ack.accepted());
  FUZZ_CHECK(ack.accepted() == ack.error().empty());
  return 0;
}
