#ifndef IMCA_COMMON_RPC_SERVICE_FLAGS_H_
#define IMCA_COMMON_RPC_SERVICE_FLAGS_H_

#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "google/protobuf/message.h"

namespace imca {

// The flags every service binary (reward_server, learner, actor) has,
// defined here once: --list, --print_config, --status_file and
// --signal_exit_code. The servers' own are in common/rpc/transport_flags.h:
// --listen and --port_file (ServeFromFlags) and the transport's
// (ServerOptionsFromFlags).
struct ServiceFlags {
  bool list = false;          // Print the binary's choices and limits as JSON and exit.
  bool print_config = false;  // Print the resolved configuration as JSON and exit.
  std::string status_file;    // Where WriteStatusFile writes ("": nowhere).
  // Exit code when SIGINT/SIGTERM stops the process before its work is done.
  int signal_exit_code = 0;
};

// Call after absl::ParseCommandLine. Errors: INVALID_ARGUMENT naming
// --signal_exit_code outside [0, 255].
absl::StatusOr<ServiceFlags> ServiceFlagsFromFlags();

// Writes a binary's one-line status record (--status_file, read by a
// supervisor such as ./imca train) atomically: `status` in protobuf's JSON
// mapping (the proto's field names, every field even at its default) with
// its singular 64-bit integers as numbers rather than quoted, so that any
// JSON reader gets numbers (the mapping's parsers accept both), plus
// "time", Unix seconds. The proto is the record's one schema (LearnerStatus,
// RewardStats, ActorStatus). Does nothing for an empty `path`. Errors:
// INTERNAL (the write, or a message the printer refuses).
absl::Status WriteStatusFile(const std::string& path, const google::protobuf::Message& status);

}  // namespace imca

#endif  // IMCA_COMMON_RPC_SERVICE_FLAGS_H_
