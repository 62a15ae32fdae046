#ifndef IMCA_LEARNER_CSV_LOG_H_
#define IMCA_LEARNER_CSV_LOG_H_

#include <cstdint>
#include <fstream>
#include <string>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"

namespace imca::learner {

// An append-only CSV file of rows keyed by a leading integer (the learner's
// iteration), that a restarted writer continues: metrics.csv and
// trained_unrolls.csv.
//
// The file is opened on the first Append. A file already there is resumed:
// its rows whose key is >= that first row's key are dropped (iterations a
// restarted learner rolled back to its checkpoint and now trains again), the
// rest stays; written atomically. A file whose header is not `header` was
// written by another version: it is renamed to <stem>.old<ext> and a fresh
// file started, rather than rows appended under columns that do not match.
//
// Not thread-safe: one writer (the learner's training thread).
class CsvLog {
 public:
  // `header` without its newline.
  CsvLog(std::string path, std::string header);

  // Appends `row` (without its newline; it begins with the integer key) and
  // flushes. Errors: INVALID_ARGUMENT if the row does not begin with an
  // integer; INTERNAL naming the file and the system error, when nothing is
  // lost but this row, and the file is reopened (and resumed) on the next
  // Append.
  absl::Status Append(absl::string_view row);

  // The last Append succeeded (true before the first): a caller reports a
  // failure once per run of failures.
  bool healthy() const { return healthy_; }
  const std::string& path() const { return path_; }

 private:
  // Opens for appending, resuming an existing file before `first_key`.
  absl::Status Open(int64_t first_key);

  const std::string path_;
  const std::string header_;
  std::ofstream out_;
  bool healthy_ = true;
};

}  // namespace imca::learner

#endif  // IMCA_LEARNER_CSV_LOG_H_
