#ifndef IMCA_COMMON_RPC_TRANSPORT_H_
#define IMCA_COMMON_RPC_TRANSPORT_H_

// Transport security of every server and client (docs/security.md): TLS or
// mutual TLS from PEM files, and a bearer token from a file, in gRPC's
// idiomatic pair: a MetadataCredentialsPlugin on the client attaches it, an
// AuthMetadataProcessor on the server credentials checks it before any
// handler runs. gRPC sends call credentials only over TLS and aborts the
// process if a processor is set on insecure server credentials, so a token
// needs TLS; plaintext with no token stays the default for loopback runs.

#include <memory>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/synchronization/mutex.h"
#include "absl/time/time.h"

namespace imca {

// Paths of PEM files and the token file; each is read when credentials are
// made. The same fields serve both roles (one set of flags per binary):
struct TransportConfig {
  // This process's certificate chain and private key: a server's (turns its
  // TLS on), or a client's (presented to a server that requires one).
  std::string tls_cert;
  std::string tls_key;
  // The CA that signs the peers: a client verifies servers against it (and
  // dials TLS); a server with require_client_cert accepts only clients with a
  // certificate it signed.
  std::string tls_ca;
  // Server: mutual TLS (the client certificate's common name is then the
  // peer's identity in the logs).
  bool require_client_cert = false;
  // Client: the name the server's certificate must carry, when it differs
  // from the dialled host (e.g. dialling 10.0.0.5 for "learner").
  std::string tls_server_name;
  // Client: the token sent (the file's first token); server: the tokens
  // accepted (every non-empty line, so that a rotation can overlap).
  std::string token_file;

  bool server_tls() const { return !tls_cert.empty(); }
  bool client_tls() const { return !tls_ca.empty(); }
};

// "plaintext", "TLS", "mutual TLS", with ", token" when one is checked or
// sent: for the line a binary logs when it starts, as a server's or a
// client's configuration.
std::string TransportSummary(const TransportConfig& config, bool server);

// INVALID_ARGUMENT naming the flag (--tls_cert, ...) when the fields do not
// make a server's, or a client's, configuration.
absl::Status ValidateServerTransport(const TransportConfig& config);
absl::Status ValidateClientTransport(const TransportConfig& config);

// The tokens of a token file: one per non-empty line, surrounding whitespace
// trimmed, each 16-4096 printable ASCII characters without spaces. Checked
// again (at most once a second) when the file's modification time or size
// changes, so a rotated Kubernetes secret takes effect without a restart; a
// file that turns unreadable or invalid keeps the last good tokens (and says
// so on stderr once). Thread-safe.
class TokenFile {
 public:
  // Errors: INVALID_ARGUMENT naming --token_file and the line (unreadable,
  // empty, or a bad token).
  static absl::StatusOr<std::shared_ptr<TokenFile>> Open(const std::string& path);

  // The first token (what a client sends).
  std::string First() ABSL_LOCKS_EXCLUDED(mu_);
  // True if `presented` is one of the tokens; compares in time independent
  // of where a wrong token first differs.
  bool Accepts(absl::string_view presented) ABSL_LOCKS_EXCLUDED(mu_);

 private:
  explicit TokenFile(std::string path) : path_(std::move(path)) {}
  // Reads the file if it changed; keeps the last good tokens on failure.
  absl::Status Load() ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  void MaybeReload() ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);

  const std::string path_;
  absl::Mutex mu_;
  std::vector<std::string> tokens_ ABSL_GUARDED_BY(mu_);
  int64_t mtime_ns_ ABSL_GUARDED_BY(mu_) = -1;
  int64_t size_ ABSL_GUARDED_BY(mu_) = -1;
  absl::Time checked_ ABSL_GUARDED_BY(mu_) = absl::InfinitePast();
  bool warned_ ABSL_GUARDED_BY(mu_) = false;
};

// The metadata key of the token ("authorization: Bearer <token>").
inline constexpr char kAuthorizationKey[] = "authorization";
// Calls to this service pass without a token (probes, load balancers).
inline constexpr char kHealthServicePrefix[] = "/grpc.health.v1.Health/";

// Server credentials for `config` (already validated): plaintext, TLS, or
// mutual TLS, with the token processor when token_file is set. Errors:
// INVALID_ARGUMENT naming the flag whose file cannot be read.
absl::StatusOr<std::shared_ptr<grpc::ServerCredentials>> MakeServerCredentials(const TransportConfig& config);

// Channel credentials for `config` (already validated): plaintext, TLS
// (optionally with a client certificate), and the token plugin when
// token_file is set. Errors: INVALID_ARGUMENT naming the flag.
absl::StatusOr<std::shared_ptr<grpc::ChannelCredentials>> MakeChannelCredentials(const TransportConfig& config);

// Who is calling, for log lines: "certificate CN=<name>" under mutual TLS,
// else "no client certificate"; then the peer's address.
std::string PeerIdentity(const grpc::ServerContext& context);

// The exit code of a client whose credentials a server refused: a supervisor
// must not restart it (the same credentials would be refused again).
inline constexpr int kExitRefused = 3;

// The exit code of a process whose configuration cannot work with its peers
// (an actor whose unroll size does not divide a synchronous learner's
// share): a supervisor must not restart it either.
inline constexpr int kExitMisconfigured = 4;

// True when a server refused this client's credentials (UNAUTHENTICATED,
// PERMISSION_DENIED): retrying cannot help, so a client stops.
bool IsRefusal(const absl::Status& status);

// True when an UNAVAILABLE on a TLS channel reads as a failed handshake (a
// certificate that does not verify, a wrong name, a plaintext peer; a server
// that requires a client certificate closes the socket on a bad one).
bool LooksLikeTlsFailure(const absl::Status& status);

// One log line for a failed call to `what` ("learner", "reward server") on a
// channel that is (`tls`) or is not TLS: what reads as a failed handshake
// says so and names the flags to check.
std::string DescribeRpcFailure(absl::string_view what, const absl::Status& status, bool tls);

}  // namespace imca

#endif  // IMCA_COMMON_RPC_TRANSPORT_H_
