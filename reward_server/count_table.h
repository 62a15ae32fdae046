#ifndef IMCA_REWARD_SERVER_COUNT_TABLE_H_
#define IMCA_REWARD_SERVER_COUNT_TABLE_H_

#include <cstdint>
#include <iosfwd>

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
  int64_t size() const { return static_cast<int64_t>(counts_.size()); }
  void Reserve(int64_t keys) { counts_.reserve(keys); }

  // Binary format: uint64 entry count, then (uint64 key, uint32 count) pairs.
  absl::Status Write(std::ostream& out) const;
  // Replaces the contents. Errors: DATA_LOSS on a truncated stream.
  absl::Status Read(std::istream& in);

 private:
  absl::flat_hash_map<uint64_t, uint32_t> counts_;
};

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_COUNT_TABLE_H_
