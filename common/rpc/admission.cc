#include "common/rpc/admission.h"

#include "absl/strings/str_cat.h"

namespace imca {

absl::StatusOr<ConcurrencyLimiter::Slot> ConcurrencyLimiter::Acquire(absl::string_view key) {
  absl::MutexLock lock(&mu_);
  if (total_ >= max_total_) {
    return absl::ResourceExhaustedError(absl::StrCat(total_, " calls in flight in total (the limit)"));
  }
  int& of_key = per_key_[key];
  if (of_key >= max_per_key_) {
    return absl::ResourceExhaustedError(absl::StrCat(of_key, " calls of this client in flight (the limit)"));
  }
  ++of_key;
  ++total_;
  return Slot(this, std::string(key));
}

void ConcurrencyLimiter::Release(const std::string& key) {
  absl::MutexLock lock(&mu_);
  --total_;
  auto it = per_key_.find(key);
  if (it != per_key_.end() && --it->second <= 0) per_key_.erase(it);
}

}  // namespace imca
