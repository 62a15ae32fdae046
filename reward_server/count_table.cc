#include "reward_server/count_table.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <istream>
#include <ostream>

#include "absl/strings/str_cat.h"
#include "common/atomic_file.h"
#include "common/status_macros.h"

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

absl::Status SaveTables(const std::string& path, const std::string& tag, const std::vector<const CountTable*>& tables) {
  return WriteFileAtomically(path, [&](std::ostream& out) {
    out << tag << "\n";
    for (const CountTable* table : tables) IMCA_RETURN_IF_ERROR(table->Write(out));
    return absl::OkStatus();
  });
}

absl::Status LoadTables(const std::string& path, const std::string& tag, const std::vector<CountTable*>& tables) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::NotFoundError(absl::StrCat("no snapshot at '", path, "'"));
  std::string written;
  std::getline(in, written);
  if (written != tag) {
    return absl::FailedPreconditionError(
        absl::StrCat("snapshot '", path, "' was written by '", written, "', not by this configuration"));
  }
  std::vector<CountTable> read(tables.size());
  for (CountTable& table : read) {
    if (absl::Status status = table.Read(in); !status.ok()) return status;
  }
  for (size_t i = 0; i < tables.size(); ++i) *tables[i] = std::move(read[i]);
  return absl::OkStatus();
}

}  // namespace imca::reward
