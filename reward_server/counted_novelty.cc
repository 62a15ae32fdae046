#include "reward_server/counted_novelty.h"

#include "common/status_macros.h"

namespace imca::reward {

absl::Status CountedNovelty::Save(const std::string& path) const {
  absl::MutexLock save_lock(&save_mu_);
  CountStore::Snapshot snapshot;
  {
    absl::MutexLock lock(&mu_);
    IMCA_ASSIGN_OR_RETURN(snapshot, store_.TakeSnapshot());
  }
  return CountStore::WriteSnapshot(path, ConfigTag(), snapshot);
}

absl::Status CountedNovelty::Load(const std::string& path) {
  absl::MutexLock lock(&mu_);
  return store_.Load(path, ConfigTag());
}

absl::Status CountedNovelty::Restore(const std::string& path, bool sync) {
  absl::MutexLock lock(&mu_);
  return store_.Restore(path, ConfigTag(), sync);
}

std::optional<int64_t> CountedNovelty::DurableTransitions() const {
  absl::MutexLock lock(&mu_);
  return store_.transitions();
}

}  // namespace imca::reward
