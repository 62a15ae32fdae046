#ifndef IMCA_REWARD_SERVER_COUNT_TABLE_H_
#define IMCA_REWARD_SERVER_COUNT_TABLE_H_

#include <cstdint>
#include <iosfwd>
#include <string>
#include <vector>

#include "absl/container/flat_hash_map.h"
#include "absl/status/status.h"

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
  void Reserve(int64_t keys) { counts_.reserve(keys); }

  // Binary format: uint64 entry count, then (uint64 key, uint32 count) pairs.
  absl::Status Write(std::ostream& out) const;
  // Replaces the contents. Errors: DATA_LOSS on a truncated stream.
  absl::Status Read(std::istream& in);

 private:
  absl::flat_hash_map<uint64_t, uint32_t> counts_;
};

// A count snapshot: one line `tag` (the writer's configuration), then the
// tables in order. Save writes it atomically (tmp file + rename): a crash
// leaves the old file or the new one, never half of it. Errors: INTERNAL
// naming the path.
absl::Status SaveTables(const std::string& path, const std::string& tag, const std::vector<const CountTable*>& tables);
// Reads a snapshot into `tables` (all or none replaced). Errors: NOT_FOUND
// (unreadable), FAILED_PRECONDITION (written under another tag), DATA_LOSS.
absl::Status LoadTables(const std::string& path, const std::string& tag, const std::vector<CountTable*>& tables);

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_COUNT_TABLE_H_
