#include "actor/unroll_sender.h"

#include <cstdio>
#include <utility>

#include "common/rpc/grpc_util.h"

namespace imca::actor {

StreamOpener PushUnrollsOf(v1::LearnerService::StubInterface* learner) {
  return [learner](grpc::ClientContext* context) { return learner->PushUnrolls(context); };
}

UnrollSender::UnrollSender(StreamOpener open, const UnrollSenderOptions& options, StopSignal* stop)
    : open_(std::move(open)), options_(options), stop_(stop), watchdog_([this] { Watch(); }) {}

UnrollSender::~UnrollSender() {
  Close();
  {
    absl::MutexLock lock(&mu_);
    watching_ = false;
  }
  watchdog_.join();
}

void UnrollSender::Close() {
  if (stream_ != nullptr) {
    stream_->WritesDone();
    stream_->Finish().ok();
  }
  stream_.reset();
  context_.reset();
  stream_acks_ = 0;
}

absl::StatusOr<v1::PushUnrollsResponse> UnrollSender::Send(v1::Unroll* unroll) {
  if (stop_->stopped()) return absl::CancelledError("the actor is stopping");
  if (stream_ != nullptr && stream_acks_ >= options_.unrolls_per_stream) Close();
  if (stream_ == nullptr) {
    context_ = std::make_unique<grpc::ClientContext>();
    // A stream lives for at most unrolls_per_stream unrolls; this deadline
    // bounds how long a hung learner can hold this actor.
    context_->set_deadline(DeadlineIn(std::chrono::minutes(10)));
    stream_ = open_(context_.get());
    stream_acks_ = 0;
    if (stream_broken_ && options_.reconnects != nullptr) options_.reconnects->Increment();
    stream_broken_ = false;
  }
  v1::PushUnrollsRequest request;
  request.mutable_unroll()->Swap(unroll);
  v1::PushUnrollsResponse ack;
  bool acked;
  {
    const StopSignal::Call call(stop_, context_.get());
    {
      absl::MutexLock lock(&mu_);
      waiting_since_ = std::chrono::steady_clock::now();
      waiting_context_ = context_.get();
    }
    const bool sent = stream_->Write(request);
    unroll->Swap(request.mutable_unroll());
    acked = sent && stream_->Read(&ack);
    absl::MutexLock lock(&mu_);
    waiting_since_.reset();
    waiting_context_ = nullptr;
  }
  if (!acked) {
    stream_broken_ = stream_acks_ > 0;
    const grpc::Status status = stream_->Finish();
    stream_.reset();
    context_.reset();
    if (stop_->stopped()) return absl::CancelledError("the actor is stopping");
    return status.ok() ? absl::UnavailableError("learner closed the stream") : FromGrpcStatus(status);
  }
  ++stream_acks_;
  return ack;
}

void UnrollSender::Watch() {
  absl::MutexLock lock(&mu_);
  while (watching_) {
    mu_.AwaitWithTimeout(absl::Condition(+[](bool* watching) { return !*watching; }, &watching_),
                         absl::Milliseconds(200));
    if (waiting_since_.has_value() && waiting_context_ != nullptr &&
        std::chrono::steady_clock::now() - *waiting_since_ > options_.ack_timeout) {
      std::fprintf(stderr, "%s: no ack from the learner for %lld ms; reconnecting\n", options_.actor_id.c_str(),
                   static_cast<long long>(options_.ack_timeout.count()));
      waiting_context_->TryCancel();
      waiting_context_ = nullptr;  // Once per wait.
    }
  }
}

}  // namespace imca::actor
