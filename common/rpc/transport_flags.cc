// The transport flags every binary shares (docs/security.md).
#include "common/rpc/transport_flags.h"

#include "absl/flags/flag.h"

ABSL_FLAG(std::string, tls_cert, "",
          "PEM certificate chain: a server's (turns TLS on), or an actor's client certificate for mutual TLS");
ABSL_FLAG(std::string, tls_key, "", "PEM private key of --tls_cert");
ABSL_FLAG(std::string, tls_ca, "",
          "PEM CA certificate: a client verifies the servers against it (and dials TLS); a server with "
          "--tls_client_auth accepts only client certificates it signed");
ABSL_FLAG(std::string, token_file, "",
          "file holding the bearer token (needs TLS): a client sends its first line, a server accepts any of "
          "its lines (rotation); re-read when it changes");

namespace imca {

TransportConfig SharedTransportFlags() {
  TransportConfig config;
  config.tls_cert = absl::GetFlag(FLAGS_tls_cert);
  config.tls_key = absl::GetFlag(FLAGS_tls_key);
  config.tls_ca = absl::GetFlag(FLAGS_tls_ca);
  config.token_file = absl::GetFlag(FLAGS_token_file);
  return config;
}

}  // namespace imca
