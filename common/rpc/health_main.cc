// imca_health: asks a server's grpc.health.v1 service whether it serves,
// over the same transport flags as an actor (TLS, client certificate); no
// token is needed. For probes (Kubernetes' own gRPC probe cannot dial TLS)
// and operators. Exit 0: SERVING; 1: not serving or unreachable; 2: bad flags.
#include <chrono>
#include <cstdio>
#include <string>

#include <grpcpp/grpcpp.h>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/flags/usage.h"
#include "common/rpc/grpc_util.h"
#include "common/rpc/transport.h"
#include "common/rpc/transport_flags.h"

ABSL_FLAG(std::string, target, "", "host:port of the server to ask");
ABSL_FLAG(int, timeout_ms, 3000, "deadline of the check");

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage("imca_health --target=host:port [--tls_ca=... ...]: exit 0 if the server serves");
  absl::ParseCommandLine(argc, argv);
  using namespace imca;
  const std::string target = absl::GetFlag(FLAGS_target);
  if (target.empty()) {
    std::fprintf(stderr, "imca_health: --target is required\n");
    return 2;
  }
  if (absl::GetFlag(FLAGS_timeout_ms) < 1) {
    std::fprintf(stderr, "imca_health: --timeout_ms must be >= 1\n");
    return 2;
  }
  absl::StatusOr<TransportConfig> transport = ClientTransportFromFlags();
  absl::StatusOr<std::shared_ptr<grpc::Channel>> channel =
      transport.ok() ? MakeChannel(target, *transport) : transport.status();
  if (!channel.ok()) {
    std::fprintf(stderr, "imca_health: %s\n", std::string(channel.status().message()).c_str());
    return 2;
  }
  const absl::StatusOr<bool> serving =
      CheckHealth(*channel, std::chrono::milliseconds(absl::GetFlag(FLAGS_timeout_ms)));
  if (!serving.ok()) {
    std::fprintf(stderr, "imca_health: %s\n",
                 DescribeRpcFailure(target, serving.status(), transport->client_tls()).c_str());
    return 1;
  }
  std::printf("%s: %s\n", target.c_str(), *serving ? "SERVING" : "NOT_SERVING");
  return *serving ? 0 : 1;
}
