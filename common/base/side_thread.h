#ifndef IMCA_COMMON_BASE_SIDE_THREAD_H_
#define IMCA_COMMON_BASE_SIDE_THREAD_H_

#include <exception>
#include <functional>
#include <thread>

#include "absl/base/thread_annotations.h"
#include "absl/synchronization/mutex.h"

namespace imca {

// One thread that runs one task at a time for its owner (the PPO trainer's
// critic pass beside the actor's): Start() hands it a task once the previous
// one has ended, Wait() blocks until it has ended and returns what it threw
// (null if nothing), Join() rethrows that. Meant for one owner thread, which
// must Wait before anything the task uses goes away. The destructor runs a
// task already started, then joins the thread.
class SideThread {
 public:
  // `on_start` runs first on the new thread (a thread-local setting such as
  // LibTorch's intra-op thread count).
  explicit SideThread(std::function<void()> on_start = nullptr);
  ~SideThread();
  SideThread(const SideThread&) = delete;
  SideThread& operator=(const SideThread&) = delete;

  // Blocks while a task is pending or running.
  void Start(std::function<void()> task) ABSL_LOCKS_EXCLUDED(mu_);
  std::exception_ptr Wait() ABSL_LOCKS_EXCLUDED(mu_);
  void Join() ABSL_LOCKS_EXCLUDED(mu_);

 private:
  void Loop() ABSL_LOCKS_EXCLUDED(mu_);
  bool Idle() const ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_) { return pending_ == nullptr && !running_; }
  bool HasWork() const ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_) { return pending_ != nullptr || stop_; }

  absl::Mutex mu_;
  std::function<void()> pending_ ABSL_GUARDED_BY(mu_);  // Started, not yet picked up.
  bool running_ ABSL_GUARDED_BY(mu_) = false;
  bool stop_ ABSL_GUARDED_BY(mu_) = false;
  std::exception_ptr error_ ABSL_GUARDED_BY(mu_);  // What the last task threw.
  std::thread thread_;  // Last: starts once the rest is constructed.
};

}  // namespace imca

#endif  // IMCA_COMMON_BASE_SIDE_THREAD_H_
