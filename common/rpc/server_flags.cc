// The servers' flags: where they listen, and their transport
// (docs/security.md).
#include <string>

#include "absl/flags/flag.h"
#include "absl/strings/str_cat.h"
#include "common/base/atomic_file.h"
#include "common/rpc/transport_flags.h"

ABSL_FLAG(std::string, listen, "",
          absl::StrCat("host:port to serve on (default: the reward server's ", imca::kDefaultRewardServerAddress,
                       ", the learner's ", imca::kDefaultLearnerAddress, "; port 0: any free port)"));
ABSL_FLAG(std::string, port_file, "", "if set, write the bound port to this file once serving");

ABSL_FLAG(bool, tls_client_auth, false,
          "mutual TLS: require a client certificate signed by --tls_ca (its common name names the client in "
          "the logs)");
ABSL_FLAG(int, max_receive_mb, imca::kMaxMessageBytes >> 20,
          "largest request accepted, MiB (larger ones end with RESOURCE_EXHAUSTED before any handler runs)");

namespace imca {

absl::StatusOr<ServerOptions> ServerOptionsFromFlags() {
  ServerOptions options;
  options.transport = SharedTransportFlags();
  options.transport.require_client_cert = absl::GetFlag(FLAGS_tls_client_auth);
  const int mb = absl::GetFlag(FLAGS_max_receive_mb);
  if (mb < 1 || mb > 2047) return absl::InvalidArgumentError("--max_receive_mb must be in [1, 2047]");
  options.max_receive_bytes = mb << 20;
  if (absl::Status valid = ValidateServerTransport(options.transport); !valid.ok()) return valid;
  return options;
}

absl::StatusOr<std::unique_ptr<grpc::Server>> ServeFromFlags(absl::string_view default_listen,
                                                             const std::vector<grpc::Service*>& services,
                                                             const ServerOptions& options, int* port) {
  std::string listen = absl::GetFlag(FLAGS_listen);
  if (listen.empty()) listen = std::string(default_listen);
  absl::StatusOr<std::unique_ptr<grpc::Server>> server = StartServer(listen, services, port, options);
  if (!server.ok()) return server.status();
  if (const std::string port_file = absl::GetFlag(FLAGS_port_file); !port_file.empty()) {
    if (absl::Status written = WriteFileAtomically(port_file, absl::StrCat(*port, "\n")); !written.ok()) {
      (*server)->Shutdown();
      return absl::InternalError(absl::StrCat("--port_file: ", written.message()));
    }
  }
  return server;
}

}  // namespace imca
