#ifndef IMCA_COMMON_RPC_GRPC_UTIL_H_
#define IMCA_COMMON_RPC_GRPC_UTIL_H_

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/rpc/transport.h"

namespace imca {

class RpcMetrics;  // common/rpc/rpc_metrics.h

// The one place where absl::Status and grpc::Status are converted.
grpc::Status ToGrpcStatus(const absl::Status& status);
absl::Status FromGrpcStatus(const grpc::Status& status);

// Installs SIGINT/SIGTERM handlers that only set an atomic flag.
void InstallShutdownSignalHandlers();
// True once SIGINT or SIGTERM arrived (or RequestShutdown was called).
bool ShutdownRequested();
void RequestShutdown();

// Largest message the servers and clients accept by default.
inline constexpr int kMaxMessageBytes = 64 << 20;
// HTTP/2 streams (calls) one client connection may hold open at once.
inline constexpr int kMaxStreamsPerConnection = 100;

// How a server listens beyond its address.
struct ServerOptions {
  TransportConfig transport;  // Default: plaintext, no token.
  // Requests larger than this end with RESOURCE_EXHAUSTED before any handler
  // runs.
  int max_receive_bytes = kMaxMessageBytes;
  // If set, every call is counted and timed into it (must outlive the server).
  RpcMetrics* rpc_metrics = nullptr;
};

// Builds and starts a gRPC server on `listen` ("host:port"; port 0 picks a
// free one) with `services`, grpc.health.v1 health checking and server
// reflection, secured as `options.transport` says. Sets *bound_port. Errors:
// INVALID_ARGUMENT naming the flag of a bad transport configuration or
// unreadable file; UNAVAILABLE "--listen: cannot listen on <address> ..."
// when it cannot be bound (e.g. the port is in use).
absl::StatusOr<std::unique_ptr<grpc::Server>> StartServer(const std::string& listen,
                                                          const std::vector<grpc::Service*>& services,
                                                          int* bound_port, const ServerOptions& options = {});

// A plaintext client channel with keepalive (kKeepaliveTimeMs) and message
// limits that fit the largest unrolls.
std::shared_ptr<grpc::Channel> MakeChannel(const std::string& target);
// The same, secured as `transport` says (TLS, client certificate, token),
// its calls counted and timed into `rpc_metrics` if set (which must outlive
// the channel). Errors: INVALID_ARGUMENT naming the flag.
absl::StatusOr<std::shared_ptr<grpc::Channel>> MakeChannel(const std::string& target,
                                                           const TransportConfig& transport,
                                                           RpcMetrics* rpc_metrics = nullptr);

// A unary call of `method` ("/pkg.Service/Method") with `request_bytes` as
// the serialized request, by gRPC's generic stub (Debian ships no
// synchronous generic call); fills *response_bytes on success. Blocks up to
// `timeout`.
grpc::Status GenericUnaryCall(const std::shared_ptr<grpc::Channel>& channel, const std::string& method,
                              const std::string& request_bytes, std::chrono::milliseconds timeout,
                              std::string* response_bytes);

// Asks the server at the other end of `channel` whether it serves, through
// grpc.health.v1.Health/Check for the server as a whole (no token needed).
// True: SERVING; false: any other answer. Errors: the call's, converted.
absl::StatusOr<bool> CheckHealth(const std::shared_ptr<grpc::Channel>& channel, std::chrono::milliseconds timeout);

// Deadline `timeout` from now, for ClientContext::set_deadline.
inline std::chrono::system_clock::time_point DeadlineIn(std::chrono::milliseconds timeout) {
  return std::chrono::system_clock::now() + timeout;
}

// Exponential backoff with full jitter for reconnect loops: 50 ms doubling to
// a 5 s cap. Not thread-safe.
class Backoff {
 public:
  // The jitter is seeded per process and object, so that many clients that
  // lost one server do not retry in lockstep.
  Backoff();
  // Sleeps for the next delay, interruptible by shutdown (checked every
  // 50 ms), or by `stopped` in the second form.
  void Wait();
  void Wait(const std::function<bool()>& stopped);
  void Reset() { attempt_ = 0; }

 private:
  int attempt_ = 0;
  uint64_t state_;
};

// Keepalive of every channel and server (both sides set together): a ping
// after this much silence, and the connection dropped if it is not answered
// within the timeout. So a dead or frozen peer shows within ~30 s.
inline constexpr int kKeepaliveTimeMs = 20000;
inline constexpr int kKeepaliveTimeoutMs = 10000;

}  // namespace imca

#endif  // IMCA_COMMON_RPC_GRPC_UTIL_H_
