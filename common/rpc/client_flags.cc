// A client's transport flags (docs/security.md).
#include "absl/flags/flag.h"
#include "common/rpc/transport_flags.h"

ABSL_FLAG(std::string, tls_server_name, "",
          "the name the servers' certificates must carry when it is not the dialled host (e.g. dialling "
          "127.0.0.1 for a certificate of 'localhost')");

namespace imca {

absl::StatusOr<TransportConfig> ClientTransportFromFlags() {
  TransportConfig config = SharedTransportFlags();
  config.tls_server_name = absl::GetFlag(FLAGS_tls_server_name);
  if (absl::Status valid = ValidateClientTransport(config); !valid.ok()) return valid;
  return config;
}

}  // namespace imca
