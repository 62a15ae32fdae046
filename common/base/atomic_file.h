#ifndef IMCA_COMMON_BASE_ATOMIC_FILE_H_
#define IMCA_COMMON_BASE_ATOMIC_FILE_H_

#include <chrono>
#include <functional>
#include <ostream>
#include <string>
#include <string_view>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace imca {

// The one way the project writes a file that must survive a crash (snapshots,
// checkpoints, policy.pb, status and trace files). `write` fills a temporary
// file beside `path` ("<path>.tmp"); the file is then flushed to disk (fsync),
// renamed over `path`, and the folder is flushed so that the rename itself
// survives a crash of the machine. A crash at any point leaves either the old
// file or the new one, complete; on any error the temporary file is removed
// and `path` is untouched.
//
// Errors: whatever `write` returns (its partial output is discarded), or
// INTERNAL naming the file and the system error. Thread-compatible: two
// concurrent writers of the same path must be serialised by their owner.
absl::Status WriteFileAtomically(const std::string& path, const std::function<absl::Status(std::ostream&)>& write);
absl::Status WriteFileAtomically(const std::string& path, std::string_view contents);

// The whole of the file at `path`. Errors: NOT_FOUND "cannot read <what>
// '<path>'" (`what` names the file's role: "map file", "token file").
absl::StatusOr<std::string> ReadFile(const std::string& path, absl::string_view what);

// fsync of a file or folder by path. Errors: INTERNAL naming it.
absl::Status SyncPath(const std::string& path);

// Seconds since the Unix epoch: the "time" of the status files the
// binaries write for a supervisor (--status_file, common/rpc/service_flags.h).
inline double UnixSeconds() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

}  // namespace imca

#endif  // IMCA_COMMON_BASE_ATOMIC_FILE_H_
