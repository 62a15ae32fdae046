#ifndef IMCA_REWARD_SERVER_NOVELTY_COUNTED_NOVELTY_H_
#define IMCA_REWARD_SERVER_NOVELTY_COUNTED_NOVELTY_H_

#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "reward_server/novelty/count_table.h"
#include "reward_server/novelty/novelty.h"

namespace imca::reward {

// A Novelty kept in count tables (count, eiti, edti): its snapshot, journal
// and durable transition count in one CountStore. Subclasses implement
// Supports, Compute, FillStats and ConfigTag, and Commit the store at the end
// of each Compute. Not thread-safe (Novelty).
class CountedNovelty : public Novelty {
 public:
  // A copy of the tables (fast); written later without the owner's lock.
  absl::StatusOr<std::unique_ptr<Snapshot>> TakeSnapshot() final;
  absl::Status Load(const std::string& path) final;
  absl::Status Restore(const std::string& path, bool sync) final;
  std::optional<int64_t> DurableTransitions() const final;
  // Deterministic scoring: the last version's increments become visible.
  absl::Status NewVersion() final {
    store_.NewVersion();
    return absl::OkStatus();
  }

 protected:
  // `deterministic`: reads go through a version view
  // (CountStore::KeepVersionView).
  CountedNovelty(int num_tables, bool deterministic) : store_(num_tables) {
    if (deterministic) store_.KeepVersionView();
  }
  // The configuration line of snapshots and journals: a file written under
  // another one is refused.
  virtual std::string ConfigTag() const = 0;

  CountStore store_;
};

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_NOVELTY_COUNTED_NOVELTY_H_
