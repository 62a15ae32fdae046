#ifndef IMCA_LEARNER_ITERATION_METRICS_H_
#define IMCA_LEARNER_ITERATION_METRICS_H_

#include <atomic>
#include <memory>
#include <string>
#include <vector>

#include "absl/container/flat_hash_map.h"
#include "common/metrics/metrics.h"

namespace imca::learner {

// What one training iteration measured: one row of <run_dir>/metrics.csv.
struct IterationRecord {
  double iteration = 0, env_steps = 0, wall_seconds = 0, env_steps_per_sec = 0;
  double success_rate = 0, train_success_rate = 0, episode_return = 0, intrinsic_reward = 0, share_max = 0;
  double policy_version = 0, policy_lag = 0, dropped_stale = 0, entropy = 0;
  // Where the iteration's wall time went, in seconds (docs/benchmarks.md).
  double wait = 0, featurise = 0, values = 0, gae = 0, copy = 0, prepare = 0, forward = 0, backward = 0,
         optimizer = 0, publish = 0;
  double global_reward = 0, contribution_abs = 0, success_episodes = 0, train_success_episodes = 0;
  double updates = 0;
  // The algorithm's own columns by name (IterationStats::values).
  absl::flat_hash_map<std::string, double> algorithm;
  std::vector<double> shares;  // p^a per agent slot: columns share_1 .. share_n.
};

// How a column reaches Prometheus.
enum class Export {
  kCsvOnly,
  kGauge,       // A gauge holding the newest iteration's value.
  kCumulative,  // A counter equal to the value (which only grows).
  kIncrement,   // A counter that grows by the value at each iteration.
};

// One column of metrics.csv and, unless CSV-only, the Prometheus family it
// feeds. This table (IterationColumns, iteration_metrics.cc) is the one
// definition of both: the CSV header and rows, the families and their help
// text, and what `learner --list` tells the Python tools. A column is every
// algorithm's (`algorithm` null, read from the record's member `value`) or
// one algorithm's own (`algorithm` its --algo name, read by `name` from the
// record's `algorithm` values): a run's metrics.csv and families hold the
// shared columns and its algorithm's.
struct Column {
  const char* name;    // CSV header.
  const char* format;  // printf format of the value.
  double scale;        // Written as value * scale (seconds as ms).
  const char* help;
  double IterationRecord::*value;  // Null for an algorithm's own column.
  Export exported;
  const char* family;     // Prometheus name, if exported.
  // --algo name of the one algorithm it belongs to (set by its registry
  // entry), or empty.
  std::string algorithm = "";
  // Measures time, not training: differs between runs that train alike
  // (what a deterministic run's comparison leaves out).
  bool wall_clock = false;
};
// Every column of every algorithm.
const std::vector<Column>& IterationColumns();
// The columns of a run of `algorithm` (an --algo name), in CSV order.
std::vector<Column> RunColumns(const std::string& algorithm);
// The names of `algorithm`'s own columns: what its IterationStats::values
// must hold.
std::vector<std::string> AlgorithmColumnNames(const std::string& algorithm);

// The CSV header of a run of `algorithm` with `num_agents` (its columns,
// then share_1..n).
std::string CsvHeader(const std::string& algorithm, int num_agents);
// The row of `record` in a run of `algorithm` (no newline). An own column
// the record lacks (the algorithm refused the iteration's batch) is nan.
std::string CsvRow(const std::string& algorithm, const IterationRecord& record);

// A run's exported columns as Prometheus families in a registry, set at
// each iteration. Thread-safe.
class IterationExporter {
 public:
  IterationExporter(metrics::Registry* registry, const std::string& algorithm);
  void Publish(const IterationRecord& record);

 private:
  const std::vector<Column> columns_;
  // Per column of the run (null where it does not apply): the gauge or
  // incremented counter, or the value a cumulative counter's callback reads.
  std::vector<metrics::Gauge*> gauges_;
  std::vector<metrics::Counter*> counters_;
  std::vector<std::atomic<double>> cumulative_;
};

}  // namespace imca::learner

#endif  // IMCA_LEARNER_ITERATION_METRICS_H_
