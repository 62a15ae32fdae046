#ifndef IMCA_COMMON_METRICS_METRICS_SERVER_H_
#define IMCA_COMMON_METRICS_METRICS_SERVER_H_

#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "absl/status/statusor.h"
#include "common/metrics/metrics.h"

namespace imca::metrics {

// Serves GET /metrics (the Prometheus text format of `registries`, rendered
// at each request) over plain HTTP on its own small thread pool, apart from
// gRPC. No authentication: bind it to loopback or a pod network only
// (docs/metrics.md). Thread-safe; the registries must outlive the server.
class MetricsServer {
 public:
  // Starts serving on `listen`: "PORT" (on 127.0.0.1) or "HOST:PORT"; port
  // 0 picks a free one. Errors: INVALID_ARGUMENT "--metrics_listen: ..." for
  // a malformed address; UNAVAILABLE "--metrics_listen: cannot listen on
  // ..." when it cannot be bound.
  static absl::StatusOr<std::unique_ptr<MetricsServer>> Start(const std::string& listen,
                                                              std::vector<const Registry*> registries);
  // Stops serving; blocks until the serving thread has ended.
  ~MetricsServer();

  int port() const { return port_; }
  const std::string& host() const { return host_; }

 private:
  struct Impl;
  MetricsServer() = default;
  std::unique_ptr<Impl> impl_;
  std::string host_;
  int port_ = 0;
  std::thread thread_;
};

// The Content-Type of the text format.
inline constexpr char kTextContentType[] = "text/plain; version=0.0.4; charset=utf-8";

}  // namespace imca::metrics

#endif  // IMCA_COMMON_METRICS_METRICS_SERVER_H_
