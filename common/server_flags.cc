// The servers' transport flags (docs/security.md).
#include "absl/flags/flag.h"
#include "absl/strings/str_cat.h"
#include "common/transport_flags.h"

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

}  // namespace imca
