#ifndef IMCA_COMMON_RPC_RPC_METRICS_H_
#define IMCA_COMMON_RPC_RPC_METRICS_H_

#include <array>
#include <atomic>
#include <memory>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>
#include <grpcpp/support/client_interceptor.h>
#include <grpcpp/support/server_interceptor.h>

#include "absl/container/flat_hash_map.h"
#include "common/metrics/metrics.h"

namespace imca {

// Counts the gRPC calls of a server or a client by method and status code
// and times them, through gRPC interceptors, into Prometheus families named
// as go-grpc-prometheus names them: imca_rpc_{server,client}_started_total
// {service, method}, imca_rpc_{server,client}_handled_total {service,
// method, code} and imca_rpc_{server,client}_handling_seconds {service,
// method} (a unary call's latency, a stream's lifetime). Methods of other
// services than those named are labelled "other", so no client can add
// series. Thread-safe; must outlive the servers and channels using it.
class RpcMetrics {
 public:
  enum class Side { kServer, kClient };

  // `services`: full service names ("imca.v1.LearnerService") whose methods
  // are looked up in the generated descriptor pool; gRPC's health service
  // (grpc.health.v1.Health) is always known.
  RpcMetrics(Side side, const std::vector<std::string>& services, metrics::Registry* registry);

  std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface> ServerInterceptorFactory();
  std::unique_ptr<grpc::experimental::ClientInterceptorFactoryInterface> ClientInterceptorFactory();

  // The index of a full method name ("/imca.v1.LearnerService/GetPolicy");
  // the "other" index for an unknown one.
  int MethodIndex(const char* full_method) const;
  void Started(int method);
  void Handled(int method, grpc::StatusCode code, double seconds);

 private:
  struct Method {
    std::string service, name;
    metrics::Counter* started;
    metrics::Histogram* seconds;
    std::array<std::atomic<metrics::Counter*>, 17> handled{};  // By status code, added at first use.
  };
  const Side side_;
  metrics::Registry* const registry_;
  std::vector<std::unique_ptr<Method>> methods_;  // Last: "other". Fixed after construction.
  absl::flat_hash_map<std::string, int> index_;   // Full method name -> methods_ index.
};

}  // namespace imca

#endif  // IMCA_COMMON_RPC_RPC_METRICS_H_
