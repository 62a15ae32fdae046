#ifndef IMCA_COMMON_RPC_TRANSPORT_FLAGS_H_
#define IMCA_COMMON_RPC_TRANSPORT_FLAGS_H_

#include <memory>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "common/rpc/grpc_util.h"
#include "common/rpc/transport.h"

namespace imca {

// Where the services listen by default (and the actors dial): --listen's
// default of each server, --reward_server and --learner's of the actor.
inline constexpr char kDefaultRewardServerAddress[] = "127.0.0.1:50051";
inline constexpr char kDefaultLearnerAddress[] = "127.0.0.1:50052";

// The transport flags of the servers: --tls_cert, --tls_key, --tls_ca,
// --tls_client_auth, --token_file and --max_receive_mb. Call after
// absl::ParseCommandLine. Errors: INVALID_ARGUMENT naming the flag.
absl::StatusOr<ServerOptions> ServerOptionsFromFlags();

// Starts a server of `services` (StartServer) on --listen, or on
// `default_listen` (the binary's own address) when the flag is not given,
// and writes the bound port to --port_file if set (atomically, for a
// supervisor that polls it). `*port` gets the bound port. Errors:
// StartServer's; INTERNAL if the port file cannot be written (the server is
// shut down).
absl::StatusOr<std::unique_ptr<grpc::Server>> ServeFromFlags(absl::string_view default_listen,
                                                             const std::vector<grpc::Service*>& services,
                                                             const ServerOptions& options, int* port);

// The transport flags of a client: --tls_ca, --tls_cert, --tls_key,
// --tls_server_name and --token_file. Errors: INVALID_ARGUMENT naming the flag.
absl::StatusOr<TransportConfig> ClientTransportFromFlags();

// The flags both roles share (--tls_cert, --tls_key, --tls_ca, --token_file),
// not validated: the two functions above build on it.
TransportConfig SharedTransportFlags();

}  // namespace imca

#endif  // IMCA_COMMON_RPC_TRANSPORT_FLAGS_H_
