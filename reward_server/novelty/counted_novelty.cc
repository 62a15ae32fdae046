#include "reward_server/novelty/counted_novelty.h"

#include <utility>

#include "common/base/status_macros.h"

namespace imca::reward {
namespace {

class CountSnapshot final : public Novelty::Snapshot {
 public:
  CountSnapshot(std::string tag, CountStore::Snapshot snapshot) : tag_(std::move(tag)), snapshot_(std::move(snapshot)) {}
  absl::Status Write(const std::string& path) const override {
    return CountStore::WriteSnapshot(path, tag_, snapshot_);
  }

 private:
  const std::string tag_;
  const CountStore::Snapshot snapshot_;
};

}  // namespace

absl::StatusOr<std::unique_ptr<Novelty::Snapshot>> CountedNovelty::TakeSnapshot() {
  IMCA_ASSIGN_OR_RETURN(CountStore::Snapshot snapshot, store_.TakeSnapshot());
  return std::make_unique<CountSnapshot>(ConfigTag(), std::move(snapshot));
}

absl::Status CountedNovelty::Load(const std::string& path) { return store_.Load(path, ConfigTag()); }

absl::Status CountedNovelty::Restore(const std::string& path, bool sync) {
  return store_.Restore(path, ConfigTag(), sync);
}

std::optional<int64_t> CountedNovelty::DurableTransitions() const { return store_.transitions(); }

}  // namespace imca::reward
