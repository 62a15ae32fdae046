#ifndef IMCA_COMMON_TRANSPORT_FLAGS_H_
#define IMCA_COMMON_TRANSPORT_FLAGS_H_

#include "absl/status/statusor.h"
#include "common/grpc_util.h"
#include "common/transport.h"

namespace imca {

// The transport flags of the servers: --tls_cert, --tls_key, --tls_ca,
// --tls_client_auth, --token_file and --max_receive_mb. Call after
// absl::ParseCommandLine. Errors: INVALID_ARGUMENT naming the flag.
absl::StatusOr<ServerOptions> ServerOptionsFromFlags();

// The transport flags of a client: --tls_ca, --tls_cert, --tls_key,
// --tls_server_name and --token_file. Errors: INVALID_ARGUMENT naming the flag.
absl::StatusOr<TransportConfig> ClientTransportFromFlags();

// The flags both roles share (--tls_cert, --tls_key, --tls_ca, --token_file),
// not validated: the two functions above build on it.
TransportConfig SharedTransportFlags();

}  // namespace imca

#endif  // IMCA_COMMON_TRANSPORT_FLAGS_H_
