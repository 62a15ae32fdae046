#include "common/base/side_thread.h"

#include <utility>

namespace imca {

SideThread::SideThread(std::function<void()> on_start)
    : thread_([this, on_start = std::move(on_start)] {
        if (on_start) on_start();
        Loop();
      }) {}

SideThread::~SideThread() {
  {
    absl::MutexLock lock(&mu_);
    stop_ = true;
  }
  thread_.join();
}

void SideThread::Start(std::function<void()> task) {
  absl::MutexLock lock(&mu_);
  mu_.Await(absl::Condition(this, &SideThread::Idle));
  pending_ = std::move(task);
}

std::exception_ptr SideThread::Wait() {
  absl::MutexLock lock(&mu_);
  mu_.Await(absl::Condition(this, &SideThread::Idle));
  return std::exchange(error_, nullptr);
}

void SideThread::Join() {
  if (std::exception_ptr error = Wait()) std::rethrow_exception(error);
}

void SideThread::Loop() {
  while (true) {
    std::function<void()> task;
    {
      absl::MutexLock lock(&mu_);
      mu_.Await(absl::Condition(this, &SideThread::HasWork));
      if (pending_ == nullptr) return;  // Stopped, nothing left to run.
      task.swap(pending_);              // Swapping cannot throw.
      running_ = true;
    }
    std::exception_ptr error;
    try {
      task();
    } catch (...) {
      error = std::current_exception();
    }
    absl::MutexLock lock(&mu_);
    error_ = error;
    running_ = false;
  }
}

}  // namespace imca
