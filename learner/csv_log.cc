#include "learner/csv_log.h"

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <system_error>
#include <utility>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "common/base/atomic_file.h"
#include "common/base/status_macros.h"

namespace imca::learner {
namespace {

namespace fs = std::filesystem;

// The integer before a row's first comma, if it is one.
bool KeyOf(absl::string_view row, int64_t* key) { return absl::SimpleAtoi(row.substr(0, row.find(',')), key); }

}  // namespace

CsvLog::CsvLog(std::string path, std::string header) : path_(std::move(path)), header_(std::move(header)) {}

absl::Status CsvLog::Open(int64_t first_key) {
  std::string existing;
  {
    std::ifstream in(path_);
    std::string line;
    bool first = true, dropped = false;
    while (in && std::getline(in, line)) {
      int64_t key = 0;
      if (first) {
        if (line != header_) break;  // Another version's file: set aside below.
        first = false;
      } else if (KeyOf(line, &key) && key >= first_key) {
        dropped = true;
        continue;
      }
      absl::StrAppend(&existing, line, "\n");
    }
    if (!first && dropped) IMCA_RETURN_IF_ERROR(WriteFileAtomically(path_, existing));
    if (first && in.is_open() && !line.empty()) {
      fs::path old = path_;
      old.replace_extension(absl::StrCat(".old", fs::path(path_).extension().string()));
      std::error_code error;
      fs::rename(path_, old, error);
      if (error) return absl::InternalError(absl::StrCat("cannot set aside ", path_, ": ", error.message()));
    }
  }
  out_.open(path_, std::ios::app);
  if (existing.empty()) out_ << header_ << "\n";
  return absl::OkStatus();
}

absl::Status CsvLog::Append(absl::string_view row) {
  absl::Status status;
  if (!out_.is_open()) {
    int64_t key = 0;
    if (!KeyOf(row, &key)) {
      healthy_ = false;
      return absl::InvalidArgumentError(absl::StrCat(path_, ": a row must begin with its integer key, got '",
                                              row.substr(0, 32), "'"));
    }
    status = Open(key);
  }
  if (status.ok()) {
    out_ << row << "\n";
    out_.flush();
    if (!out_) status = absl::InternalError(absl::StrCat("cannot write ", path_, ": ", std::strerror(errno)));
  }
  if (!status.ok()) {
    // Reopened (and resumed) on the next row.
    out_.close();
    out_.clear();
  }
  healthy_ = status.ok();
  return status;
}

}  // namespace imca::learner
