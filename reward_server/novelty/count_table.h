#ifndef IMCA_REWARD_SERVER_NOVELTY_COUNT_TABLE_H_
#define IMCA_REWARD_SERVER_NOVELTY_COUNT_TABLE_H_

#include <sys/types.h>

#include <cstdint>
#include <iosfwd>
#include <string>
#include <vector>

#include "absl/container/flat_hash_map.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace imca::reward {

// Visit counts keyed by 64-bit keys (see JointKeyCodec for how keys are made).
// An open-addressing hash map of 16-byte slots: 10^7 keys take ~300 MB.
// Not thread-safe; the owner serialises access.
class CountTable {
 public:
  uint32_t Get(uint64_t key) const {
    auto it = counts_.find(key);
    return it == counts_.end() ? 0 : it->second;
  }
  void Increment(uint64_t key) { ++counts_[key]; }
  void Add(uint64_t key, uint32_t count) { counts_[key] += count; }
  int64_t size() const { return static_cast<int64_t>(counts_.size()); }
  void Clear() { counts_.clear(); }
  void Reserve(int64_t keys) { counts_.reserve(keys); }

  // Binary format: uint64 entry count, then (uint64 key, uint32 count) pairs
  // in key order, so that equal tables write equal bytes.
  absl::Status Write(std::ostream& out) const;
  // Replaces the contents. Errors: DATA_LOSS on a truncated stream.
  absl::Status Read(std::istream& in);

 private:
  absl::flat_hash_map<uint64_t, uint32_t> counts_;
};

// The count tables of one reward kind with crash-safe persistence: a
// snapshot file (written whole or not at all, common/base/atomic_file.h) plus an
// append-only journal of every increment since it, so that a kill -9 loses
// no increment whose Score was answered (docs/reliability.md).
//
// Files: the snapshot at `path` (a line with the owner's tag, a line
// "journal <epoch> <transitions>", then the tables), and journals
// "<path>.journal-<epoch>", each a header line "IMCA-JOURNAL-1 <tag>" then
// records of one Commit: uint32 magic, uint32 payload bytes, uint64 FNV-1a
// checksum of the payload; payload: int64 transitions, then (uint8 table,
// uint64 key, uint32 count) entries. A snapshot of epoch E holds everything
// journaled before epoch E; Restore replays the journals of epoch >= E in
// order and stops at a torn or corrupt record (a write cut off by a kill,
// whose Score was never answered).
//
// Not thread-safe: the owner serialises every call but WriteSnapshot (see
// TakeSnapshot).
class CountStore {
 public:
  explicit CountStore(int num_tables) : tables_(num_tables) {}
  ~CountStore();
  CountStore(const CountStore&) = delete;
  CountStore& operator=(const CountStore&) = delete;

  const CountTable& table(int i) const { return tables_[i]; }
  // The count Score reads: the table's, or with a version view, the table's
  // as the current version began plus the current call's own increments.
  uint32_t Get(int table, uint64_t key) const {
    if (version_delta_.empty()) return tables_[table].Get(key);
    return tables_[table].Get(key) - version_delta_[table].Get(key) + call_delta_[table].Get(key);
  }
  // Applies at once; journaled by the next Commit.
  void Increment(int table, uint64_t key) { Add(table, key, 1); }
  void Add(int table, uint64_t key, uint32_t count);

  // Deterministic scoring (ScorerConfig::deterministic): from now on Get
  // reads through a version view, so that the calls of one policy version
  // do not see each other's increments (which are applied and journaled at
  // once as ever: the tables, snapshots and journals do not change).
  void KeepVersionView();
  // Starts a version: the increments so far become visible to every call.
  void NewVersion();

  // Ends one Score call: counts `transitions` and appends the increments
  // since the last Commit to the journal in one write(), before the caller
  // answers. Without a journal (no Restore yet) it only counts. With `sync`
  // (Restore's) the write is also fdatasync'ed, which survives a crash of the
  // machine, not only of the process. Errors: INTERNAL if the write fails
  // (the increments stay applied in memory).
  absl::Status Commit(int64_t transitions);
  // Transitions counted by Commit, over the life of the snapshot and journals.
  int64_t transitions() const { return transitions_; }

  // Loads the snapshot at `path` if there is one, replays its journals, and
  // journals from now on to a new "<path>.journal-<epoch>". Errors:
  // FAILED_PRECONDITION if a file was written under another `tag`;
  // DATA_LOSS for a damaged snapshot; INTERNAL if the journal cannot be
  // opened. Nothing is changed on error.
  absl::Status Restore(const std::string& path, const std::string& tag, bool sync = false);

  // A copy of the tables taken under the owner's lock, to be written
  // without it. Starting the next epoch's journal is part of taking it, so
  // every later increment goes to a journal the snapshot does not cover.
  struct Snapshot {
    std::vector<CountTable> tables;
    int64_t epoch = 0;
    int64_t transitions = 0;
  };
  absl::StatusOr<Snapshot> TakeSnapshot();
  // Writes `snapshot` to `path` and deletes the journals it covers. Thread-
  // safe against the owner's other calls; serialise WriteSnapshot calls.
  // Errors: INTERNAL naming the file.
  static absl::Status WriteSnapshot(const std::string& path, const std::string& tag, const Snapshot& snapshot);
  // Replaces the tables with a snapshot file's, ignoring any journal (an
  // explicit load of a snapshot, not a recovery). Errors: NOT_FOUND,
  // FAILED_PRECONDITION, DATA_LOSS; nothing is changed on error.
  absl::Status Load(const std::string& path, const std::string& tag);

 private:
  absl::Status OpenJournal(int64_t epoch);

  std::vector<CountTable> tables_;
  int64_t transitions_ = 0;
  std::string path_;  // Of the snapshot; empty until Restore.
  std::string tag_;
  int64_t epoch_ = 0;  // Of the open journal.
  int journal_fd_ = -1;
  off_t journal_bytes_ = 0;  // Of complete records (and the header) in the open journal.
  bool sync_ = false;
  std::string pending_;  // Entries since the last Commit.
  // The version view (KeepVersionView; empty without one): the increments of
  // the current version's calls, and of the current call.
  std::vector<CountTable> version_delta_;
  std::vector<CountTable> call_delta_;
};

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_NOVELTY_COUNT_TABLE_H_
