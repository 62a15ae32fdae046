#ifndef IMCA_COMMON_RPC_ADMISSION_H_
#define IMCA_COMMON_RPC_ADMISSION_H_

#include <string>

#include "absl/base/thread_annotations.h"
#include "absl/container/flat_hash_map.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/synchronization/mutex.h"

namespace imca {

// Bounds the calls in flight: at most `max_total` at once, and at most
// `max_per_key` with one key (a client's name), so that one client that
// floods a server takes its own slots only and the others still get theirs.
// Never blocks: a call over a bound is refused at once. Memory is bounded
// by the calls in flight (a key's entry goes with its last slot).
// Thread-safe.
class ConcurrencyLimiter {
 public:
  ConcurrencyLimiter(int max_total, int max_per_key) : max_total_(max_total), max_per_key_(max_per_key) {}
  // Only the total bound: every Acquire() without a key shares it.
  explicit ConcurrencyLimiter(int max_total) : ConcurrencyLimiter(max_total, max_total) {}

  // A held slot; released when destroyed. Movable.
  class Slot {
   public:
    Slot(Slot&& other) noexcept : limiter_(other.limiter_), key_(std::move(other.key_)) { other.limiter_ = nullptr; }
    Slot& operator=(Slot&&) = delete;
    ~Slot() {
      if (limiter_ != nullptr) limiter_->Release(key_);
    }

   private:
    friend class ConcurrencyLimiter;
    Slot(ConcurrencyLimiter* limiter, std::string key) : limiter_(limiter), key_(std::move(key)) {}
    ConcurrencyLimiter* limiter_;
    std::string key_;
  };

  // A slot for a call of `key`. Errors: RESOURCE_EXHAUSTED saying which
  // bound is reached ("per client" or "in total") and its value.
  absl::StatusOr<Slot> Acquire(absl::string_view key = "") ABSL_LOCKS_EXCLUDED(mu_);

 private:
  void Release(const std::string& key) ABSL_LOCKS_EXCLUDED(mu_);

  const int max_total_;
  const int max_per_key_;
  absl::Mutex mu_;
  int total_ ABSL_GUARDED_BY(mu_) = 0;
  absl::flat_hash_map<std::string, int> per_key_ ABSL_GUARDED_BY(mu_);
};

}  // namespace imca

#endif  // IMCA_COMMON_RPC_ADMISSION_H_
