#ifndef IMCA_COMMON_METRICS_METRICS_TESTING_H_
#define IMCA_COMMON_METRICS_METRICS_TESTING_H_

// Test helpers for Prometheus expositions (common/metrics/metrics.h).

#include <string>

namespace imca::metrics::testing {

// The value of the series line `series` ("name" or "name{labels}", exactly
// as rendered) in the exposition `text`; -1 if it has no such line.
inline double SampleValue(const std::string& text, const std::string& series) {
  const std::string key = "\n" + series + " ";
  const size_t at = ("\n" + text).find(key);  // Offset in "\n" + text.
  return at == std::string::npos ? -1 : std::stod(text.substr(at + key.size() - 1));
}

}  // namespace imca::metrics::testing

#endif  // IMCA_COMMON_METRICS_METRICS_TESTING_H_
