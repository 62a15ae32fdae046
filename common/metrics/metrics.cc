#include "common/metrics/metrics.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace imca::metrics {
namespace {

[[noreturn]] void Misuse(const std::string& what) {
  std::fprintf(stderr, "metrics: %s\n", what.c_str());
  std::abort();
}

void AddAtomic(std::atomic<double>* value, double by) {
  double old = value->load(std::memory_order_relaxed);
  while (!value->compare_exchange_weak(old, old + by, std::memory_order_relaxed)) {
  }
}

bool ValidName(const std::string& name, bool label) {
  if (name.empty()) return false;
  for (size_t i = 0; i < name.size(); ++i) {
    const char c = name[i];
    const bool ok = (c >= 'a' && c <= 'z') || c == '_' || (i > 0 && c >= '0' && c <= '9') || (!label && c == ':');
    if (!ok) return false;
  }
  return !absl::StartsWith(name, "__");
}

const char* TypeName(Type type) {
  switch (type) {
    case Type::kCounter:
      return "counter";
    case Type::kGauge:
      return "gauge";
    case Type::kHistogram:
      return "histogram";
  }
  return "untyped";
}

void CheckFamily(const Family& family) {
  const std::string name = family.name;
  if (!ValidName(name, /*label=*/false)) Misuse(absl::StrCat("invalid metric name '", name, "'"));
  if (family.help == nullptr || *family.help == '\0') Misuse(absl::StrCat(name, ": no help text"));
  const bool total = absl::EndsWith(name, "_total");
  if ((family.type == Type::kCounter) != total) {
    Misuse(absl::StrCat(name, ": counters and only counters end in _total"));
  }
  for (const char* suffix : {"_bucket", "_sum", "_count", "_ms", "_sec", "_secs", "_kb", "_mb", "_per_sec"}) {
    if (absl::EndsWith(name, suffix)) Misuse(absl::StrCat(name, ": reserved suffix or abbreviated unit ", suffix));
  }
  if (family.type == Type::kHistogram) {
    if (family.buckets.empty()) Misuse(absl::StrCat(name, ": a histogram needs buckets"));
    for (size_t i = 0; i < family.buckets.size(); ++i) {
      if (!std::isfinite(family.buckets[i]) || (i > 0 && !(family.buckets[i] > family.buckets[i - 1]))) {
        Misuse(absl::StrCat(name, ": buckets must be finite and strictly increasing"));
      }
    }
  } else if (!family.buckets.empty()) {
    Misuse(absl::StrCat(name, ": only histograms have buckets"));
  }
}

std::string FormatValue(double v) {
  if (std::isnan(v)) return "NaN";
  if (std::isinf(v)) return v > 0 ? "+Inf" : "-Inf";
  if (v == std::floor(v) && std::abs(v) < 1e15) return absl::StrFormat("%.0f", v);
  // The shortest of 15-17 significant digits that reads back exactly.
  for (int digits = 15; digits < 17; ++digits) {
    const std::string text = absl::StrFormat("%.*g", digits, v);
    if (std::strtod(text.c_str(), nullptr) == v) return text;
  }
  return absl::StrFormat("%.17g", v);
}

std::string EscapeHelp(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '\\') {
      out += "\\\\";
    } else if (c == '\n') {
      out += "\\n";
    } else {
      out += c;
    }
  }
  return out;
}

std::string EscapeLabel(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '\\') {
      out += "\\\\";
    } else if (c == '"') {
      out += "\\\"";
    } else if (c == '\n') {
      out += "\\n";
    } else {
      out += c;
    }
  }
  return out;
}

// `{a="x",b="y"}` (with `extra` last), or "" without labels.
std::string LabelText(const Labels& labels, const std::pair<std::string, std::string>* extra = nullptr) {
  if (labels.empty() && extra == nullptr) return "";
  std::string out = "{";
  bool first = true;
  auto add = [&](const std::pair<std::string, std::string>& label) {
    absl::StrAppend(&out, first ? "" : ",", label.first, "=\"", EscapeLabel(label.second), "\"");
    first = false;
  };
  for (const auto& label : labels) add(label);
  if (extra != nullptr) add(*extra);
  out += "}";
  return out;
}

}  // namespace

void Counter::Increment(double by) {
  if (!(by >= 0) || std::isinf(by)) return;
  AddAtomic(&value_, by);
}

void Gauge::Add(double by) { AddAtomic(&value_, by); }

Histogram::Histogram(std::vector<double> bounds) : bounds_(std::move(bounds)), counts_(bounds_.size() + 1, 0) {}

void Histogram::Observe(double value) {
  if (std::isnan(value)) return;
  const size_t bucket = std::lower_bound(bounds_.begin(), bounds_.end(), value) - bounds_.begin();
  absl::MutexLock lock(&mu_);
  ++counts_[bucket];
  sum_ += value;
}

Histogram::Snapshot Histogram::Take() const {
  Snapshot s;
  s.bounds = bounds_;
  absl::MutexLock lock(&mu_);
  uint64_t running = 0;
  for (uint64_t c : counts_) {
    running += c;
    s.cumulative.push_back(running);
  }
  s.count = running;
  s.sum = sum_;
  return s;
}

std::vector<double> ExponentialBuckets(double start, double factor, int count) {
  std::vector<double> out;
  double bound = start;
  for (int i = 0; i < count; ++i, bound *= factor) out.push_back(bound);
  return out;
}

Registry::Series* Registry::Find(const Family& family, const Labels& labels) {
  CheckFamily(family);
  for (const auto& label : labels) {
    if (!ValidName(label.first, /*label=*/true) || (family.type == Type::kHistogram && label.first == "le")) {
      Misuse(absl::StrCat(family.name, ": invalid label name '", label.first, "'"));
    }
  }
  FamilyEntry* entry = nullptr;
  for (const auto& e : families_) {
    if (std::string(e->family.name) == family.name) entry = e.get();
  }
  if (entry == nullptr) {
    families_.push_back(std::make_unique<FamilyEntry>(FamilyEntry{family, {}}));
    entry = families_.back().get();
  } else if (entry->family.type != family.type || std::string(entry->family.help) != family.help ||
             entry->family.buckets != family.buckets) {
    Misuse(absl::StrCat(family.name, ": registered twice with different definitions"));
  }
  for (const auto& series : entry->series) {
    if (series->labels == labels) return series.get();
  }
  if (!entry->series.empty()) {
    const Labels& first = entry->series.front()->labels;
    bool same_names = first.size() == labels.size();
    for (size_t i = 0; same_names && i < labels.size(); ++i) same_names = first[i].first == labels[i].first;
    if (!same_names) Misuse(absl::StrCat(family.name, ": every series needs the same label names"));
  }
  entry->series.push_back(std::make_unique<Series>());
  Series* series = entry->series.back().get();
  series->labels = labels;
  return series;
}

template <typename T, typename... Args>
T& Registry::AddValue(const Family& family, const Labels& labels, Type type, std::unique_ptr<T> Series::*slot,
                      Args&&... args) {
  if (family.type != type) Misuse(absl::StrCat(family.name, ": not a ", TypeName(type)));
  absl::MutexLock lock(&mu_);
  Series* series = Find(family, labels);
  if (series->read != nullptr) Misuse(absl::StrCat(family.name, ": series already read by a callback"));
  if (series->*slot == nullptr) series->*slot = std::make_unique<T>(std::forward<Args>(args)...);
  return *(series->*slot);
}

Counter& Registry::AddCounter(const Family& family, const Labels& labels) {
  return AddValue(family, labels, Type::kCounter, &Series::counter);
}

std::vector<Counter*> Registry::AddCounterPerValue(const Family& family, const std::string& label,
                                                   const std::vector<std::string>& values) {
  std::vector<Counter*> counters(values.size(), nullptr);
  for (size_t i = 0; i < values.size(); ++i) {
    if (!values[i].empty()) counters[i] = &AddCounter(family, {{label, values[i]}});
  }
  return counters;
}

Gauge& Registry::AddGauge(const Family& family, const Labels& labels) {
  return AddValue(family, labels, Type::kGauge, &Series::gauge);
}

Histogram& Registry::AddHistogram(const Family& family, const Labels& labels) {
  return AddValue(family, labels, Type::kHistogram, &Series::histogram, family.buckets);
}

void Registry::AddCallback(const Family& family, std::function<double()> read, const Labels& labels) {
  if (family.type == Type::kHistogram) Misuse(absl::StrCat(family.name, ": a callback cannot be a histogram"));
  absl::MutexLock lock(&mu_);
  Series* series = Find(family, labels);
  if (series->counter != nullptr || series->gauge != nullptr) {
    Misuse(absl::StrCat(family.name, ": series already has a value object"));
  }
  series->read = std::make_shared<std::function<double()>>(std::move(read));
}

void Snapshot::Set(const Family& family, double value) {
  if (learning_) {
    families_.push_back(family);
    values_.push_back(value);
    return;
  }
  if (next_ >= families_.size() || std::string(families_[next_].name) != family.name) {
    Misuse(absl::StrCat(family.name, ": a snapshot must set the same families in the same order each time"));
  }
  values_[next_++] = value;
}

void Registry::AddSnapshot(std::function<void(Snapshot&)> read) {
  struct Group {
    absl::Mutex mu;
    Snapshot snapshot ABSL_GUARDED_BY(mu);
    std::function<void(Snapshot&)> read;
  };
  auto group = std::make_shared<Group>();
  group->read = std::move(read);
  std::vector<Family> families;
  {
    absl::MutexLock lock(&group->mu);
    group->read(group->snapshot);
    group->snapshot.learning_ = false;
    families = group->snapshot.families_;
  }
  for (size_t i = 0; i < families.size(); ++i) {
    AddCallback(families[i], [group, i] {
      absl::MutexLock lock(&group->mu);
      return group->snapshot.values_[i];
    });
  }
  absl::MutexLock lock(&mu_);
  collectors_.push_back(std::make_shared<std::function<void()>>([group] {
    absl::MutexLock lock(&group->mu);
    group->snapshot.next_ = 0;
    group->read(group->snapshot);
  }));
}

void Registry::AppendText(std::string* out) const {
  // What to render, copied under the lock; the callbacks run outside it.
  struct Row {
    const Series* series;
    std::shared_ptr<std::function<double()>> read;
  };
  std::vector<std::pair<const FamilyEntry*, std::vector<Row>>> snapshot;
  std::vector<std::shared_ptr<std::function<void()>>> collectors;
  {
    absl::MutexLock lock(&mu_);
    collectors = collectors_;
    for (const auto& entry : families_) {
      std::vector<Row> rows;
      for (const auto& series : entry->series) rows.push_back(Row{series.get(), series->read});
      snapshot.emplace_back(entry.get(), std::move(rows));
    }
  }
  for (const auto& collect : collectors) (*collect)();
  for (const auto& [entry, rows] : snapshot) {
    const Family& f = entry->family;
    absl::StrAppend(out, "# HELP ", f.name, " ", EscapeHelp(f.help), "\n# TYPE ", f.name, " ", TypeName(f.type),
                    "\n");
    for (const Row& row : rows) {
      const Series& s = *row.series;
      if (s.histogram != nullptr) {
        const Histogram::Snapshot h = s.histogram->Take();
        for (size_t i = 0; i <= h.bounds.size(); ++i) {
          const std::pair<std::string, std::string> le{"le", i < h.bounds.size() ? FormatValue(h.bounds[i]) : "+Inf"};
          absl::StrAppend(out, f.name, "_bucket", LabelText(s.labels, &le), " ", h.cumulative[i], "\n");
        }
        absl::StrAppend(out, f.name, "_sum", LabelText(s.labels), " ", FormatValue(h.sum), "\n");
        absl::StrAppend(out, f.name, "_count", LabelText(s.labels), " ", h.count, "\n");
        continue;
      }
      const double value = row.read != nullptr ? (*row.read)()
                           : s.counter != nullptr ? s.counter->value()
                                                  : s.gauge->value();
      absl::StrAppend(out, f.name, LabelText(s.labels), " ", FormatValue(value), "\n");
    }
  }
}

std::string Registry::Text() const {
  std::string out;
  AppendText(&out);
  return out;
}

std::vector<std::string> Registry::FamilyNames() const {
  absl::MutexLock lock(&mu_);
  std::vector<std::string> names;
  for (const auto& entry : families_) names.push_back(entry->family.name);
  return names;
}

std::string SharedFamily(const std::vector<const Registry*>& registries) {
  std::set<std::string> names;
  for (const Registry* registry : registries) {
    for (const std::string& name : registry->FamilyNames()) {
      if (!names.insert(name).second) return name;
    }
  }
  return "";
}

std::string Text(const std::vector<const Registry*>& registries) {
  if (const std::string shared = SharedFamily(registries); !shared.empty()) {
    Misuse(absl::StrCat(shared, ": exported by two registries"));
  }
  std::string out;
  for (const Registry* registry : registries) registry->AppendText(&out);
  return out;
}

namespace {

// Fields of /proc/self/statm, in pages: size, resident.
std::pair<double, double> MemoryBytes() {
  std::ifstream statm("/proc/self/statm");
  double size = 0, resident = 0;
  statm >> size >> resident;
  const double page = static_cast<double>(sysconf(_SC_PAGESIZE));
  return {size * page, resident * page};
}

double CpuSeconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_utime.tv_sec + usage.ru_stime.tv_sec + 1e-6 * (usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
}

double CountEntries(const char* dir) {
  std::error_code error;
  double n = 0;
  for (std::filesystem::directory_iterator it(dir, error), end; !error && it != end; it.increment(error)) ++n;
  return n;
}

}  // namespace

// The process's start in Unix seconds: /proc/self/stat's starttime (clock
// ticks since boot, field 22) plus /proc/stat's btime; now if unreadable.
double StartTime() {
  std::string stat;
  std::getline(std::ifstream("/proc/self/stat"), stat);
  // Fields after the command name, which is in parentheses and may hold spaces.
  const size_t close = stat.rfind(')');
  std::istringstream fields(close == std::string::npos ? "" : stat.substr(close + 2));
  std::string field;
  double ticks = -1;
  for (int i = 3; i <= 22 && fields >> field; ++i) {
    if (i == 22) ticks = std::strtod(field.c_str(), nullptr);
  }
  double boot = -1;
  std::ifstream proc_stat("/proc/stat");
  for (std::string line; std::getline(proc_stat, line);) {
    if (absl::StartsWith(line, "btime ")) boot = std::strtod(line.c_str() + 6, nullptr);
  }
  if (ticks < 0 || boot < 0) {
    return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  }
  return boot + ticks / static_cast<double>(sysconf(_SC_CLK_TCK));
}

void AddProcessMetrics(Registry* registry) {
  const double start = StartTime();
  registry->AddCallback({"process_resident_memory_bytes", Type::kGauge, "Resident memory size in bytes."},
                        [] { return MemoryBytes().second; });
  registry->AddCallback({"process_virtual_memory_bytes", Type::kGauge, "Virtual memory size in bytes."},
                        [] { return MemoryBytes().first; });
  registry->AddCallback({"process_cpu_seconds_total", Type::kCounter, "Total user and system CPU time spent in seconds."},
                        CpuSeconds);
  registry->AddCallback({"process_open_fds", Type::kGauge, "Number of open file descriptors."},
                        [] { return CountEntries("/proc/self/fd"); });
  registry->AddCallback({"process_threads", Type::kGauge, "Number of OS threads in the process."},
                        [] { return CountEntries("/proc/self/task"); });
  registry->AddCallback({"process_start_time_seconds", Type::kGauge,
                         "Start time of the process since unix epoch in seconds."},
                        [start] { return start; });
}

}  // namespace imca::metrics
