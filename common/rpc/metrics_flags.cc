#include "common/rpc/metrics_flags.h"

#include <cstdio>
#include <string>

#include "absl/flags/flag.h"

ABSL_FLAG(std::string, metrics_listen, "",
          "serve Prometheus metrics at http://HOST:PORT/metrics: PORT (on 127.0.0.1) or HOST:PORT (0.0.0.0:PORT "
          "in a container); port 0 picks a free one; empty: no endpoint. Plain HTTP, no authentication");

namespace imca {

ProcessMetrics::ProcessMetrics(RpcMetrics::Side side, const std::vector<std::string>& services)
    : rpc(side, services, &registry) {
  metrics::AddProcessMetrics(&registry);
}

absl::StatusOr<std::unique_ptr<metrics::MetricsServer>> ProcessMetrics::Serve(
    const char* program, std::vector<const metrics::Registry*> components) {
  const std::string listen = absl::GetFlag(FLAGS_metrics_listen);
  if (listen.empty()) return nullptr;
  components.insert(components.begin(), &registry);
  absl::StatusOr<std::unique_ptr<metrics::MetricsServer>> server =
      metrics::MetricsServer::Start(listen, std::move(components));
  if (server.ok()) {
    std::fprintf(stderr, "%s: metrics on http://%s:%d/metrics\n", program, (*server)->host().c_str(),
                 (*server)->port());
  }
  return server;
}

}  // namespace imca
