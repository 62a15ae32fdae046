#ifndef IMCA_LEARNER_ALGORITHMS_REGISTRY_H_
#define IMCA_LEARNER_ALGORITHMS_REGISTRY_H_

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "base/json.h"
#include "base/settings.h"
#include "env/env.h"
#include "learner/algorithms/interface.h"
#include "learner/iteration_metrics.h"
#include "learner/learner_config.h"

namespace imca::learner {

// The learner's algorithms, each registered from its own folder
// (mappo/mappo_registration.cc, ...) by one call in registry.cc's list, the
// one place that names them all. An entry carries everything the learner,
// its binary and the tools know of an algorithm: nothing outside its folder
// names it.
struct AlgorithmEntry {
  std::string name;  // --algo; also metrics.csv's and the columns' owner.
  std::string help;  // One line: what it is (--algo's help, --list).
  // Sets the algorithm's differences from LearnerConfig's defaults on
  // `scenario` (collection, budget) and its own options (config->options) to
  // its defaults there, the scenario's tuning (env::TuningOf) included.
  std::function<void(absl::string_view scenario, LearnerConfig* config)> defaults;
  // Its settings (base/settings.h): the rows --list prints, the flags given
  // set over config->options (errors: INVALID_ARGUMENT naming the flag), and
  // the options as "flag": value (--print_config).
  std::vector<SettingRow> settings;
  std::function<absl::Status(LearnerConfig* config)> fill_from_flags;
  std::function<void(const LearnerConfig& config, JsonObject* json)> add_json;
  // Its own columns of metrics.csv (Column::algorithm is set to `name` when
  // registered): what its IterationStats::values hold.
  std::vector<Column> columns;
  // The algorithm for `scenario` (which must outlive it) with `config`.
  // Errors: INVALID_ARGUMENT for a configuration it refuses (options of
  // another algorithm among them); INTERNAL.
  std::function<absl::StatusOr<std::unique_ptr<Algorithm>>(const env::Scenario* scenario,
                                                          const LearnerConfig& config)>
      create;
};

// A closed set of entries. Built once, then read-only (thread-safe to read).
class AlgorithmRegistry {
 public:
  // Errors: INVALID_ARGUMENT for an empty or taken name or a missing hook.
  absl::Status Add(AlgorithmEntry entry);
  // The entry named `name` ("" names the first registered, the default).
  // Errors: INVALID_ARGUMENT "--algo: 'x' is not a, b or c".
  absl::StatusOr<const AlgorithmEntry*> Find(absl::string_view name) const;
  std::vector<std::string> Names() const;
  const std::vector<AlgorithmEntry>& entries() const { return entries_; }

 private:
  std::vector<AlgorithmEntry> entries_;
};

// The registry of every algorithm (registry.cc's list), built on first use.
const AlgorithmRegistry& Algorithms();

// The defaults of a learner of `scenario` trained by `algo` (a registered
// name, "" for the default), in the order they join: LearnerConfig's, the
// scenario's tuning (env::TuningOf, beside the scenario's spec), then the
// algorithm's entry. The one definition every way of starting the learner
// resolves (the binary's flags override it, --list prints it per scenario).
// Errors: INVALID_ARGUMENT for an unknown algorithm.
absl::StatusOr<LearnerConfig> DefaultLearnerConfig(absl::string_view scenario, absl::string_view algo);

// Helpers for an entry whose options are a T (MappoOptions, ...): the
// options `config` holds, refusing another algorithm's (INVALID_ARGUMENT).
template <typename T>
absl::StatusOr<const T*> CheckedOptions(const LearnerConfig& config) {
  if (config.options.has_value() && OptionsIf<T>(config) == nullptr) {
    return absl::InvalidArgumentError("the learner config holds another algorithm's options (config.options)");
  }
  return &OptionsOf<T>(config);
}

}  // namespace imca::learner

#endif  // IMCA_LEARNER_ALGORITHMS_REGISTRY_H_
