#ifndef IMCA_COMMON_METRICS_FLAGS_H_
#define IMCA_COMMON_METRICS_FLAGS_H_

#include <memory>
#include <vector>

#include "absl/status/statusor.h"
#include "common/metrics.h"
#include "common/metrics_server.h"

namespace imca {

// Starts the Prometheus endpoint --metrics_listen asks for, serving
// `registries`, and logs its address as "<program>: metrics on http://...".
// Returns nullptr when the flag is empty (no endpoint). Errors: those of
// MetricsServer::Start, naming --metrics_listen.
absl::StatusOr<std::unique_ptr<metrics::MetricsServer>> StartMetricsFromFlags(
    const char* program, std::vector<const metrics::Registry*> registries);

}  // namespace imca

#endif  // IMCA_COMMON_METRICS_FLAGS_H_
