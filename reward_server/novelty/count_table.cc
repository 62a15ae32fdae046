#include "reward_server/novelty/count_table.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <istream>
#include <ostream>
#include <sstream>
#include <utility>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "common/base/atomic_file.h"
#include "common/base/hash.h"
#include "common/base/status_macros.h"

namespace imca::reward {

absl::Status CountTable::Write(std::ostream& out) const {
  // In key order: the hash map's order changes from process to process
  // (absl salts its hash), and equal tables must give equal bytes.
  std::vector<std::pair<uint64_t, uint32_t>> sorted(counts_.begin(), counts_.end());
  std::sort(sorted.begin(), sorted.end());
  const uint64_t entries = sorted.size();
  out.write(reinterpret_cast<const char*>(&entries), sizeof(entries));
  for (const auto& [key, count] : sorted) {
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

namespace {

namespace fs = std::filesystem;

constexpr uint32_t kRecordMagic = 0x4a434d49;  // "IMCJ"
constexpr char kJournalHeader[] = "IMCA-JOURNAL-1 ";
constexpr char kEpochLine[] = "journal ";
constexpr size_t kEntryBytes = 1 + 8 + 4;

template <typename T>
void Put(std::string* out, T value) {
  out->append(reinterpret_cast<const char*>(&value), sizeof(value));
}

template <typename T>
T Take(const char* p) {
  T value;
  std::memcpy(&value, p, sizeof(value));
  return value;
}

std::string JournalPath(const std::string& path, int64_t epoch) {
  return absl::StrCat(path, ".journal-", absl::Dec(epoch, absl::kZeroPad8));
}

// The journals of `path` by epoch, ascending.
std::vector<std::pair<int64_t, std::string>> Journals(const std::string& path) {
  std::vector<std::pair<int64_t, std::string>> found;
  const fs::path snapshot(path);
  const fs::path dir = snapshot.parent_path().empty() ? fs::path(".") : snapshot.parent_path();
  const std::string prefix = snapshot.filename().string() + ".journal-";
  std::error_code error;
  for (const auto& entry : fs::directory_iterator(dir, error)) {
    const std::string name = entry.path().filename().string();
    int64_t epoch;
    if (name.rfind(prefix, 0) == 0 && absl::SimpleAtoi(name.substr(prefix.size()), &epoch)) {
      found.emplace_back(epoch, (dir / name).string());
    }
  }
  std::sort(found.begin(), found.end());
  return found;
}

struct SnapshotFile {
  std::vector<CountTable> tables;
  int64_t epoch = 0;
  int64_t transitions = 0;
};

absl::StatusOr<SnapshotFile> ReadSnapshot(const std::string& path, const std::string& tag, int num_tables) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::NotFoundError(absl::StrCat("no snapshot at '", path, "'"));
  std::string written;
  std::getline(in, written);
  if (written != tag) {
    return absl::FailedPreconditionError(
        absl::StrCat("snapshot '", path, "' was written by '", written, "', not by this configuration"));
  }
  SnapshotFile file;
  // Snapshots from before the journal have no epoch line (the tables'
  // leading entry count never spells "journal ").
  char peek[sizeof(kEpochLine) - 1];
  const std::streampos tables_start = in.tellg();
  if (in.read(peek, sizeof(peek)) && std::string(peek, sizeof(peek)) == kEpochLine) {
    std::string line;
    std::getline(in, line);
    std::istringstream fields(line);
    if (!(fields >> file.epoch >> file.transitions)) {
      return absl::DataLossError(absl::StrCat("snapshot '", path, "': bad journal line"));
    }
  } else {
    in.clear();
    in.seekg(tables_start);
  }
  file.tables.resize(num_tables);
  for (CountTable& table : file.tables) IMCA_RETURN_IF_ERROR(table.Read(in));
  return file;
}

// Applies the journal at `path` to `tables`; returns the transitions it
// counted. A torn or corrupt record ends it (logged).
absl::StatusOr<int64_t> Replay(const std::string& path, const std::string& tag, std::vector<CountTable>* tables) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::InternalError(absl::StrCat("cannot read journal '", path, "'"));
  std::string header;
  std::getline(in, header);
  if (header.rfind(kJournalHeader, 0) != 0 || header.substr(sizeof(kJournalHeader) - 1) != tag) {
    if (header.empty() && in.eof()) return 0;  // Created, nothing written yet.
    return absl::FailedPreconditionError(
        absl::StrCat("journal '", path, "' was written by '", header, "', not by this configuration"));
  }
  int64_t transitions = 0, records = 0;
  std::string payload;
  while (true) {
    char head[16];
    if (!in.read(head, sizeof(head))) {
      if (in.gcount() != 0) std::fprintf(stderr, "reward_server: %s: torn record header after %lld records\n",
                                         path.c_str(), static_cast<long long>(records));
      break;
    }
    const uint32_t bytes = Take<uint32_t>(head + 4);
    if (Take<uint32_t>(head) != kRecordMagic || bytes < 8 || (bytes - 8) % kEntryBytes != 0) {
      std::fprintf(stderr, "reward_server: %s: corrupt record after %lld records; ignoring the rest\n",
                   path.c_str(), static_cast<long long>(records));
      break;
    }
    payload.resize(bytes);
    if (!in.read(payload.data(), bytes) || Fnv1a(payload) != Take<uint64_t>(head + 8)) {
      std::fprintf(stderr, "reward_server: %s: torn record after %lld records (a write cut off)\n",
                   path.c_str(), static_cast<long long>(records));
      break;
    }
    transitions += Take<int64_t>(payload.data());
    for (size_t at = 8; at < bytes; at += kEntryBytes) {
      const uint8_t table = static_cast<uint8_t>(payload[at]);
      if (table >= tables->size()) return absl::DataLossError(absl::StrCat("journal '", path, "': bad table"));
      (*tables)[table].Add(Take<uint64_t>(payload.data() + at + 1), Take<uint32_t>(payload.data() + at + 9));
    }
    ++records;
  }
  return transitions;
}

}  // namespace

CountStore::~CountStore() {
  if (journal_fd_ >= 0) ::close(journal_fd_);
}

void CountStore::KeepVersionView() {
  version_delta_.assign(tables_.size(), CountTable());
  call_delta_.assign(tables_.size(), CountTable());
}

void CountStore::NewVersion() {
  for (CountTable& delta : version_delta_) delta.Clear();
  for (CountTable& delta : call_delta_) delta.Clear();
}

void CountStore::Add(int table, uint64_t key, uint32_t count) {
  tables_[table].Add(key, count);
  if (!version_delta_.empty()) {
    version_delta_[table].Add(key, count);
    call_delta_[table].Add(key, count);
  }
  if (journal_fd_ < 0) return;
  Put(&pending_, static_cast<uint8_t>(table));
  Put(&pending_, key);
  Put(&pending_, count);
}

absl::Status CountStore::Commit(int64_t transitions) {
  transitions_ += transitions;
  for (CountTable& delta : call_delta_) delta.Clear();
  if (journal_fd_ < 0 || (pending_.empty() && transitions == 0)) return absl::OkStatus();
  // Record: magic, payload bytes, checksum; payload: transitions, entries.
  std::string record;
  record.reserve(16 + 8 + pending_.size());
  Put(&record, kRecordMagic);
  Put(&record, static_cast<uint32_t>(8 + pending_.size()));
  Put(&record, uint64_t{0});  // The checksum, filled in below.
  Put(&record, transitions);
  record += pending_;
  pending_.clear();
  const uint64_t checksum = Fnv1a({record.data() + 16, record.size() - 16});
  std::memcpy(record.data() + 8, &checksum, sizeof(checksum));
  // One write of the whole record (O_APPEND): a kill -9 after it returns
  // loses nothing, the page cache belongs to the kernel.
  // A failed write is cut back off, so that the records after it (later
  // answered Scores) are not hidden behind a torn one on replay.
  const auto fail = [&](const char* what) {
    const int saved_errno = errno;
    if (::ftruncate(journal_fd_, journal_bytes_) != 0) {
      std::fprintf(stderr, "reward_server: cannot cut a failed journal record: %s\n", std::strerror(errno));
    }
    return absl::InternalError(absl::StrCat("journal ", what, ": ", std::strerror(saved_errno)));
  };
  for (size_t done = 0; done < record.size();) {
    const ssize_t wrote = ::write(journal_fd_, record.data() + done, record.size() - done);
    if (wrote < 0) {
      if (errno == EINTR) continue;
      return fail("write");
    }
    done += static_cast<size_t>(wrote);
  }
  if (sync_ && ::fdatasync(journal_fd_) != 0) return fail("fdatasync");
  journal_bytes_ += static_cast<off_t>(record.size());
  return absl::OkStatus();
}

absl::Status CountStore::OpenJournal(int64_t epoch) {
  const std::string journal = JournalPath(path_, epoch);
  const int fd = ::open(journal.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0644);
  if (fd < 0) return absl::InternalError(absl::StrCat("cannot open journal '", journal, "': ", std::strerror(errno)));
  const std::string header = absl::StrCat(kJournalHeader, tag_, "\n");
  if (::write(fd, header.data(), header.size()) != static_cast<ssize_t>(header.size()) || ::fsync(fd) != 0) {
    ::close(fd);
    return absl::InternalError(absl::StrCat("cannot write journal '", journal, "': ", std::strerror(errno)));
  }
  // The new file's name must survive too.
  const fs::path dir = fs::path(journal).parent_path();
  if (absl::Status synced = SyncPath(dir.empty() ? "." : dir.string()); !synced.ok()) {
    ::close(fd);
    return synced;
  }
  if (journal_fd_ >= 0) ::close(journal_fd_);
  journal_fd_ = fd;
  journal_bytes_ = static_cast<off_t>(header.size());
  epoch_ = epoch;
  return absl::OkStatus();
}

absl::Status CountStore::Restore(const std::string& path, const std::string& tag, bool sync) {
  SnapshotFile file;
  if (std::ifstream(path).good()) {
    IMCA_ASSIGN_OR_RETURN(file, ReadSnapshot(path, tag, static_cast<int>(tables_.size())));
  } else {
    file.tables.resize(tables_.size());
  }
  int64_t epoch = file.epoch;
  for (const auto& [journal_epoch, journal] : Journals(path)) {
    if (journal_epoch < file.epoch) continue;  // Covered by the snapshot; deleted once it was written.
    IMCA_ASSIGN_OR_RETURN(const int64_t transitions, Replay(journal, tag, &file.tables));
    file.transitions += transitions;
    epoch = std::max(epoch, journal_epoch);
  }
  const std::string old_path = path_, old_tag = tag_;
  path_ = path;
  tag_ = tag;
  if (absl::Status opened = OpenJournal(epoch + 1); !opened.ok()) {
    path_ = old_path;
    tag_ = old_tag;
    return opened;
  }
  tables_ = std::move(file.tables);
  NewVersion();
  transitions_ = file.transitions;
  sync_ = sync;
  pending_.clear();
  return absl::OkStatus();
}

absl::StatusOr<CountStore::Snapshot> CountStore::TakeSnapshot() {
  Snapshot snapshot;
  if (journal_fd_ >= 0) IMCA_RETURN_IF_ERROR(OpenJournal(epoch_ + 1));
  snapshot.tables = tables_;
  snapshot.epoch = epoch_;
  snapshot.transitions = transitions_;
  return snapshot;
}

absl::Status CountStore::WriteSnapshot(const std::string& path, const std::string& tag, const Snapshot& snapshot) {
  IMCA_RETURN_IF_ERROR(WriteFileAtomically(path, [&](std::ostream& out) {
    out << tag << "\n" << kEpochLine << snapshot.epoch << " " << snapshot.transitions << "\n";
    for (const CountTable& table : snapshot.tables) IMCA_RETURN_IF_ERROR(table.Write(out));
    return absl::OkStatus();
  }));
  for (const auto& [epoch, journal] : Journals(path)) {
    if (epoch < snapshot.epoch) std::remove(journal.c_str());
  }
  return absl::OkStatus();
}

absl::Status CountStore::Load(const std::string& path, const std::string& tag) {
  IMCA_ASSIGN_OR_RETURN(SnapshotFile file, ReadSnapshot(path, tag, static_cast<int>(tables_.size())));
  tables_ = std::move(file.tables);
  NewVersion();
  transitions_ = file.transitions;
  return absl::OkStatus();
}

}  // namespace imca::reward
