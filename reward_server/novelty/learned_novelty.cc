#include "reward_server/novelty/learned_novelty.h"

#include <algorithm>
#include <exception>
#include <tuple>
#include <utility>

#include "absl/strings/str_cat.h"
#include "common/base/atomic_file.h"
#include "common/base/status_macros.h"

namespace imca::reward {
namespace {

class BytesSnapshot final : public Novelty::Snapshot {
 public:
  explicit BytesSnapshot(std::string bytes) : bytes_(std::move(bytes)) {}
  absl::Status Write(const std::string& path) const override { return WriteFileAtomically(path, bytes_); }

 private:
  const std::string bytes_;
};

}  // namespace

LearnedNovelty::LearnedNovelty(std::string kind, std::string credit, NoveltyReads reads, bool deterministic)
    : kind_(std::move(kind)), credit_(std::move(credit)), reads_(reads), deterministic_(deterministic) {}

absl::Status LearnedNovelty::CheckNetwork(absl::string_view kind, const std::vector<int>& hidden,
                                          double learning_rate, double gamma) {
  for (int h : hidden) {
    if (h < 1) return absl::InvalidArgumentError(absl::StrCat(kind, " hidden sizes must be >= 1"));
  }
  if (!(learning_rate > 0)) return absl::InvalidArgumentError(absl::StrCat(kind, " learning rate must be > 0"));
  if (!(gamma >= 0 && gamma < 1)) return absl::InvalidArgumentError(absl::StrCat(kind, " gamma must be in [0, 1)"));
  return absl::OkStatus();
}

absl::Status LearnedNovelty::Compute(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out) {
  const bool local = out.local != nullptr;
  if (reads_ == NoveltyReads::kNothing || local != (reads_ == NoveltyReads::kLocal)) {
    return absl::InternalError(absl::StrCat(kind_, ": no ", local ? "local" : "joint", " model for credit rule ",
                                            credit_));
  }
  Deferred updates;
  Deferred* deferred = deterministic_ && !dry_run ? &updates : nullptr;
  try {
    if (local) {
      ComputeLocal(batch, dry_run, out, deferred);
    } else {
      ComputeJoint(batch, dry_run, out, deferred);
    }
  } catch (const std::exception& e) {
    return absl::InternalError(absl::StrCat(kind_, ": ", e.what()));
  }
  if (deferred != nullptr) {
    updates.push_back([this] { EndRequest(/*dry_run=*/false); });
    pending_.push_back(Pending{std::string(batch.actor_id), batch.sequence, batch.incarnation, std::move(updates)});
  } else {
    EndRequest(dry_run);
  }
  return absl::OkStatus();
}

absl::Status LearnedNovelty::NewVersion() {
  std::sort(pending_.begin(), pending_.end(), [](const Pending& a, const Pending& b) {
    return std::tie(a.actor_id, a.sequence, a.incarnation) < std::tie(b.actor_id, b.sequence, b.incarnation);
  });
  size_t done = 0;  // Calls whose updates all ran (or threw: dropped, not retried).
  absl::Status status;
  for (; done < pending_.size() && status.ok(); ++done) {
    try {
      for (const auto& update : pending_[done].updates) update();
    } catch (const std::exception& e) {
      status = absl::InternalError(absl::StrCat(kind_, ": the last version's updates of ", pending_[done].actor_id,
                                                " #", pending_[done].sequence, ": ", e.what()));
    }
  }
  pending_.erase(pending_.begin(), pending_.begin() + done);
  return status;
}

absl::StatusOr<std::unique_ptr<Novelty::Snapshot>> LearnedNovelty::TakeSnapshot() {
  IMCA_ASSIGN_OR_RETURN(std::string bytes, Serialize());
  return std::make_unique<BytesSnapshot>(std::move(bytes));
}

}  // namespace imca::reward
