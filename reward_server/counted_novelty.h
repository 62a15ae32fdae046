#ifndef IMCA_REWARD_SERVER_COUNTED_NOVELTY_H_
#define IMCA_REWARD_SERVER_COUNTED_NOVELTY_H_

#include <cstdint>
#include <optional>
#include <string>

#include "absl/base/thread_annotations.h"
#include "absl/synchronization/mutex.h"
#include "reward_server/count_table.h"
#include "reward_server/novelty.h"

namespace imca::reward {

// A Novelty kept in count tables (count, eiti, edti): its snapshot, journal
// and durable transition count in one CountStore, under the mutex its
// Compute also takes. Subclasses implement Supports, Compute, FillStats and
// ConfigTag, and Commit the store at the end of each Compute. Thread-safe.
class CountedNovelty : public Novelty {
 public:
  // Copies the tables under mu_ (fast) and writes them without it, so that
  // Score is not blocked by I/O.
  absl::Status Save(const std::string& path) const final;
  absl::Status Load(const std::string& path) final;
  absl::Status Restore(const std::string& path, bool sync) final;
  std::optional<int64_t> DurableTransitions() const final;

 protected:
  explicit CountedNovelty(int num_tables) : store_(num_tables) {}
  // The configuration line of snapshots and journals: a file written under
  // another one is refused.
  virtual std::string ConfigTag() const = 0;

  mutable absl::Mutex mu_;
  // Mutable: taking a snapshot (Save, const) starts the next journal.
  mutable CountStore store_ ABSL_GUARDED_BY(mu_);

 private:
  mutable absl::Mutex save_mu_ ABSL_ACQUIRED_BEFORE(mu_);  // Serialises whole snapshot writes.
};

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_COUNTED_NOVELTY_H_
