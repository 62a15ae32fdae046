#ifndef IMCA_COMMON_METRICS_METRICS_H_
#define IMCA_COMMON_METRICS_METRICS_H_

// Prometheus metrics: counters, gauges and histograms in a Registry that
// renders the text exposition format (version 0.0.4). No HTTP here
// (common/metrics/metrics_server.h serves registries) and no gRPC
// (common/rpc/rpc_metrics.h counts calls).
//
// Each metric family is a `Family` constant defined once, in the component
// that exports it (docs/metrics.md lists them all). Label values must come
// from small fixed sets (a method, a code, a reason): never an agent, an
// actor id or an episode.

#include <atomic>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/synchronization/mutex.h"

namespace imca::metrics {

enum class Type { kCounter, kGauge, kHistogram };

// A metric family's definition. Names follow Prometheus conventions
// (checked when registered): lower snake case, base units (_seconds,
// _bytes, _ratio), counters end in _total and nothing else does.
struct Family {
  const char* name;
  Type type;
  const char* help;
  // Histograms only: bucket upper bounds, finite and strictly increasing
  // (+Inf is implicit).
  std::vector<double> buckets = {};
};

// (name, value) pairs, in the order rendered.
using Labels = std::vector<std::pair<std::string, std::string>>;

// Monotone. Thread-safe, lock-free.
class Counter {
 public:
  // `by` < 0 or not finite is ignored (a counter never goes down).
  void Increment(double by = 1);
  double value() const { return value_.load(std::memory_order_relaxed); }

 private:
  std::atomic<double> value_{0};
};

// Thread-safe, lock-free.
class Gauge {
 public:
  void Set(double value) { value_.store(value, std::memory_order_relaxed); }
  void Add(double by);
  double value() const { return value_.load(std::memory_order_relaxed); }

 private:
  std::atomic<double> value_{0};
};

// Counts observations into cumulative buckets. Thread-safe; a scrape sees
// one consistent state (the +Inf bucket equals the count).
class Histogram {
 public:
  explicit Histogram(std::vector<double> bounds);
  // A NaN is ignored.
  void Observe(double value);

  struct Snapshot {
    std::vector<double> bounds;
    std::vector<uint64_t> cumulative;  // One per bound, then +Inf (== count).
    double sum = 0;
    uint64_t count = 0;
  };
  Snapshot Take() const;

 private:
  const std::vector<double> bounds_;
  mutable absl::Mutex mu_;
  std::vector<uint64_t> counts_ ABSL_GUARDED_BY(mu_);  // Per bucket, not cumulative; last is +Inf.
  double sum_ ABSL_GUARDED_BY(mu_) = 0;
};

// Bucket bounds `start`, start*factor, ... (`count` of them).
std::vector<double> ExponentialBuckets(double start, double factor, int count);

// The values one Registry::AddSnapshot read sets together (see there).
class Snapshot {
 public:
  // Sets `family`'s value: counters and gauges without labels, in the same
  // order at every call (misuse aborts).
  void Set(const Family& family, double value);

 private:
  friend class Registry;
  bool learning_ = true;          // The first call: Set adds families.
  std::vector<Family> families_;  // In the order Set named them.
  std::vector<double> values_;
  size_t next_ = 0;
};

// A set of metric families. Registration is get-or-create: adding a series
// (family + labels) that exists returns the existing one, so call sites may
// add lazily (e.g. a new status code). Misuse is a programming error and
// aborts with a message: an invalid or misnamed family, a family added again
// with another type, help or buckets, labels whose names differ from the
// family's first series, or an invalid label name. Objects returned live as
// long as the registry. Thread-safe; callbacks run on the scraping thread,
// outside the registry's lock, and must not call into it.
class Registry {
 public:
  Registry() = default;
  Registry(const Registry&) = delete;
  Registry& operator=(const Registry&) = delete;

  Counter& AddCounter(const Family& family, const Labels& labels = {});
  // One counter of `family` per value of `label`, all registered (at 0) now,
  // in the order of `values`; an empty value has none (null), so an enum's
  // names index its counters.
  std::vector<Counter*> AddCounterPerValue(const Family& family, const std::string& label,
                                           const std::vector<std::string>& values);
  Gauge& AddGauge(const Family& family, const Labels& labels = {});
  Histogram& AddHistogram(const Family& family, const Labels& labels = {});
  // A counter or gauge series whose value `read` returns at each scrape
  // (for values the component already keeps, such as its status). A
  // counter's must be monotone. Adding the same series again replaces `read`.
  void AddCallback(const Family& family, std::function<double()> read, const Labels& labels = {});
  // Series that one `read` sets together at each scrape (Snapshot::Set),
  // taking one lock and one consistent view of the component's state
  // instead of one per series. `read` runs once here, to learn its
  // families, and then once per scrape before any value is rendered.
  void AddSnapshot(std::function<void(Snapshot&)> read);

  // Appends the text exposition of every family, in registration order.
  void AppendText(std::string* out) const;
  std::string Text() const;
  // Names of the registered families.
  std::vector<std::string> FamilyNames() const;

 private:
  struct Series {
    Labels labels;
    std::unique_ptr<Counter> counter;
    std::unique_ptr<Gauge> gauge;
    std::unique_ptr<Histogram> histogram;
    std::shared_ptr<std::function<double()>> read;
  };
  struct FamilyEntry {
    Family family;
    std::vector<std::unique_ptr<Series>> series;
  };
  // The series of `family` with `labels`, created if missing.
  Series* Find(const Family& family, const Labels& labels) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  // Add{Counter,Gauge,Histogram}: the series' value object in `slot`,
  // made from `args` if missing.
  template <typename T, typename... Args>
  T& AddValue(const Family& family, const Labels& labels, Type type, std::unique_ptr<T> Series::*slot,
              Args&&... args);

  mutable absl::Mutex mu_;
  std::vector<std::unique_ptr<FamilyEntry>> families_ ABSL_GUARDED_BY(mu_);
  std::vector<std::shared_ptr<std::function<void()>>> collectors_ ABSL_GUARDED_BY(mu_);
};

// Renders several registries into one exposition. Aborts if a family name
// is in two of them (each name has one owner; MetricsServer::Start checks
// it before serving).
std::string Text(const std::vector<const Registry*>& registries);
// The first family name that two of `registries` hold ("" if none).
std::string SharedFamily(const std::vector<const Registry*>& registries);

// The standard process_* families of Prometheus clients, read at each
// scrape from /proc: resident and virtual memory, CPU seconds, open file
// descriptors, threads, and the start time.
void AddProcessMetrics(Registry* registry);

}  // namespace imca::metrics

#endif  // IMCA_COMMON_METRICS_METRICS_H_
