#ifndef IMCA_LEARNER_ITERATION_METRICS_H_
#define IMCA_LEARNER_ITERATION_METRICS_H_

#include <atomic>
#include <memory>
#include <string>
#include <vector>

#include "common/metrics.h"

namespace imca::learner {

// What one training iteration measured: one row of <run_dir>/metrics.csv.
struct IterationRecord {
  double iteration = 0, env_steps = 0, wall_seconds = 0, env_steps_per_sec = 0;
  double success_rate = 0, train_success_rate = 0, episode_return = 0, intrinsic_reward = 0, share_max = 0;
  double policy_version = 0, policy_lag = 0, dropped_stale = 0;
  double policy_loss = 0, value_loss = 0, entropy = 0, approx_kl = 0, clip_fraction = 0, behaviour_kl = 0;
  // Where the iteration's wall time went, in seconds (docs/benchmarks.md).
  double wait = 0, featurise = 0, values = 0, gae = 0, copy = 0, prepare = 0, forward = 0, backward = 0,
         optimizer = 0, publish = 0;
  double global_reward = 0, contribution_abs = 0, success_episodes = 0, train_success_episodes = 0;
  double voi_reward = 0, updates = 0, replay_size = 0;
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
// feeds. This table (kIterationColumns, iteration_metrics.cc) is the one
// definition of both: the CSV header and rows, the families and their help
// text, and what `learner --list` tells the Python tools.
struct Column {
  const char* name;    // CSV header.
  const char* format;  // printf format of the value.
  double scale;        // Written as value * scale (seconds as ms).
  const char* help;
  double IterationRecord::*value;
  Export exported;
  const char* family;  // Prometheus name, if exported.
};
const std::vector<Column>& IterationColumns();

// The CSV header for `num_agents` (the table's columns, then share_1..n).
std::string CsvHeader(int num_agents);
// The row of `record` (no newline).
std::string CsvRow(const IterationRecord& record);

// The exported columns as Prometheus families in a registry, set at each
// iteration. Thread-safe.
class IterationExporter {
 public:
  explicit IterationExporter(metrics::Registry* registry);
  void Publish(const IterationRecord& record);

 private:
  // Per column of the table (null where it does not apply): the gauge or
  // incremented counter, or the value a cumulative counter's callback reads.
  std::vector<metrics::Gauge*> gauges_;
  std::vector<metrics::Counter*> counters_;
  std::vector<std::atomic<double>> cumulative_;
};

}  // namespace imca::learner

#endif  // IMCA_LEARNER_ITERATION_METRICS_H_
