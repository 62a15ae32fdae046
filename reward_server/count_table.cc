#include "reward_server/count_table.h"

#include <algorithm>
#include <istream>
#include <ostream>

namespace imca::reward {

absl::Status CountTable::Write(std::ostream& out) const {
  const uint64_t entries = counts_.size();
  out.write(reinterpret_cast<const char*>(&entries), sizeof(entries));
  for (const auto& [key, count] : counts_) {
    out.write(reinterpret_cast<const char*>(&key), sizeof(key));
    out.write(reinterpret_cast<const char*>(&count), sizeof(count));
  }
  return out ? absl::OkStatus() : absl::InternalError("count table write failed");
}

absl::Status CountTable::Read(std::istream& in) {
  uint64_t entries = 0;
  if (!in.read(reinterpret_cast<char*>(&entries), sizeof(entries))) {
    return absl::DataLossError("count table: missing entry count");
  }
  absl::flat_hash_map<uint64_t, uint32_t> counts;
  // A corrupt count must not trigger a giant allocation: reserve at most 2^26.
  counts.reserve(std::min<uint64_t>(entries, uint64_t{1} << 26));
  for (uint64_t i = 0; i < entries; ++i) {
    uint64_t key;
    uint32_t count;
    if (!in.read(reinterpret_cast<char*>(&key), sizeof(key)) ||
        !in.read(reinterpret_cast<char*>(&count), sizeof(count))) {
      return absl::DataLossError("count table: truncated entries");
    }
    counts[key] = count;
  }
  counts_.swap(counts);
  return absl::OkStatus();
}

}  // namespace imca::reward
