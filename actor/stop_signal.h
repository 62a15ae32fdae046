#ifndef IMCA_ACTOR_STOP_SIGNAL_H_
#define IMCA_ACTOR_STOP_SIGNAL_H_

#include <atomic>

#include <grpcpp/grpcpp.h>

#include "absl/base/thread_annotations.h"
#include "absl/synchronization/mutex.h"
#include "common/rpc/grpc_util.h"

namespace imca::actor {

// A stop request for one actor: set by Stop() (from any thread) or by the
// process's shutdown signal, it also cancels the gRPC call the actor's thread
// is waiting on, so that no wait outlasts it by more than a poll. Thread-safe.
class StopSignal {
 public:
  // Sets the signal and cancels the call in flight, if any.
  void Stop() {
    absl::MutexLock lock(&mu_);
    stopped_.store(true, std::memory_order_relaxed);
    if (in_flight_ != nullptr) in_flight_->TryCancel();
  }
  // True after Stop() or once the process was asked to shut down.
  bool stopped() const { return stopped_.load(std::memory_order_relaxed) || ShutdownRequested(); }

  // Registers `context` as the call in flight for its lifetime (one at a
  // time: the actor's thread makes one call at a time); cancelled at once if
  // the signal is already set.
  class Call {
   public:
    Call(StopSignal* signal, grpc::ClientContext* context) : signal_(signal) {
      absl::MutexLock lock(&signal_->mu_);
      signal_->in_flight_ = context;
      if (signal_->stopped_.load(std::memory_order_relaxed)) context->TryCancel();
    }
    ~Call() {
      absl::MutexLock lock(&signal_->mu_);
      signal_->in_flight_ = nullptr;
    }
    Call(const Call&) = delete;
    Call& operator=(const Call&) = delete;

   private:
    StopSignal* signal_;
  };

 private:
  absl::Mutex mu_;
  std::atomic<bool> stopped_{false};
  grpc::ClientContext* in_flight_ ABSL_GUARDED_BY(mu_) = nullptr;
};

}  // namespace imca::actor

#endif  // IMCA_ACTOR_STOP_SIGNAL_H_
