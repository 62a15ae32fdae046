#ifndef IMCA_ACTOR_UNROLL_SENDER_H_
#define IMCA_ACTOR_UNROLL_SENDER_H_

#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include <grpcpp/grpcpp.h>

#include "absl/base/thread_annotations.h"
#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"
#include "actor/stop_signal.h"
#include "common/metrics/metrics.h"
#include "imca/v1/learner_service.grpc.pb.h"

namespace imca::actor {

using PushStream = grpc::ClientReaderWriterInterface<v1::PushUnrollsRequest, v1::PushUnrollsResponse>;
// Opens a PushUnrolls stream on `context`: the learner stub's PushUnrolls,
// or a fake stream in tests.
using StreamOpener = std::function<std::unique_ptr<PushStream>(grpc::ClientContext* context)>;

// The opener of a real learner's streams; `learner` must outlive it.
StreamOpener PushUnrollsOf(v1::LearnerService::StubInterface* learner);

struct UnrollSenderOptions {
  std::string actor_id = "actor-0";  // In log lines.
  int unrolls_per_stream = 256;      // A stream is closed and reopened after this many acks.
  // Longest wait for one unroll's ack (the learner delays acks while its
  // queue is full, by up to an iteration): past it the stream is cancelled,
  // logged, and Send fails so that the unroll is resent on a new stream.
  std::chrono::milliseconds ack_timeout{60000};
  // Counted when a stream is opened after one that had been acknowledged
  // broke (not at each attempt while the learner is not there yet). May be
  // null.
  metrics::Counter* reconnects = nullptr;
};

// The actor's unroll stream to the learner: sends one unroll at a time and
// waits for its ack, opening streams as needed (one per unrolls_per_stream
// acks, and a new one after a failure), with a watchdog thread that cancels
// a stream whose ack is overdue. What to do with a failure or a rejection is
// the caller's: Send reports it. Not thread-safe, except that the StopSignal
// may be set from any thread: it cancels a Send in flight, and later Sends
// fail at once.
class UnrollSender {
 public:
  // Starts the watchdog. `stop` must outlive the sender.
  UnrollSender(StreamOpener open, const UnrollSenderOptions& options, StopSignal* stop);
  // Close(), and joins the watchdog.
  ~UnrollSender();
  UnrollSender(const UnrollSender&) = delete;
  UnrollSender& operator=(const UnrollSender&) = delete;

  // Sends *unroll (moved in and back out, not copied) and waits for its ack.
  // Returns the ack (accepted, or a typed rejection); on failure the stream
  // is dropped and the error returned: the learner's status (UNAVAILABLE,
  // OUT_OF_RANGE once its budget is done, ...), UNAVAILABLE if it closed the
  // stream without one, CANCELLED after a stop or an overdue ack.
  absl::StatusOr<v1::PushUnrollsResponse> Send(v1::Unroll* unroll);
  // Half-closes the stream and waits for the learner to end it.
  void Close();

 private:
  void Watch();

  const StreamOpener open_;
  const UnrollSenderOptions options_;
  StopSignal* const stop_;
  std::unique_ptr<grpc::ClientContext> context_;
  std::unique_ptr<PushStream> stream_;
  int stream_acks_ = 0;
  bool stream_broken_ = false;  // A stream that had an ack broke: the next one is a reconnect.

  absl::Mutex mu_;
  bool watching_ ABSL_GUARDED_BY(mu_) = true;
  std::optional<std::chrono::steady_clock::time_point> waiting_since_ ABSL_GUARDED_BY(mu_);
  grpc::ClientContext* waiting_context_ ABSL_GUARDED_BY(mu_) = nullptr;
  std::thread watchdog_;
};

}  // namespace imca::actor

#endif  // IMCA_ACTOR_UNROLL_SENDER_H_
