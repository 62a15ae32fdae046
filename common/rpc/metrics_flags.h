#ifndef IMCA_COMMON_RPC_METRICS_FLAGS_H_
#define IMCA_COMMON_RPC_METRICS_FLAGS_H_

#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "common/metrics/metrics.h"
#include "common/metrics/metrics_server.h"
#include "common/rpc/rpc_metrics.h"

namespace imca {

// What every binary exports besides its components' own families: the
// process_* families and its gRPC calls (wire `rpc` into ServerOptions or
// MakeChannel). Must outlive the servers, channels and endpoint using it.
struct ProcessMetrics {
  // `services`: the gRPC services whose calls are labelled by method.
  ProcessMetrics(RpcMetrics::Side side, const std::vector<std::string>& services);
  // Starts the Prometheus endpoint --metrics_listen asks for, serving this
  // registry and `components`, and logs its address as "<program>: metrics
  // on http://...". Returns nullptr when the flag is empty (no endpoint).
  // Errors: those of MetricsServer::Start, naming --metrics_listen.
  absl::StatusOr<std::unique_ptr<metrics::MetricsServer>> Serve(const char* program,
                                                                std::vector<const metrics::Registry*> components);

  metrics::Registry registry;
  RpcMetrics rpc;
};

}  // namespace imca

#endif  // IMCA_COMMON_RPC_METRICS_FLAGS_H_
