#ifndef IMCA_LEARNER_ALGORITHMS_REGISTRY_H_
#define IMCA_LEARNER_ALGORITHMS_REGISTRY_H_

#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "common/base/json.h"
#include "common/base/registry.h"
#include "common/base/settings.h"
#include "common/base/status_macros.h"
#include "common/env/env.h"
#include "learner/algorithms/interface.h"
#include "learner/iteration_metrics.h"
#include "learner/learner_config.h"

namespace imca::learner {

// The learner's algorithms, each registered from its own folder
// (mappo/mappo_registration.cc, ...); algorithms.def, one line each, is the
// one place that names them all. An entry carries everything the learner,
// its binary and the tools know of an algorithm: nothing outside its folder
// names it.
struct AlgorithmEntry {
  std::string name;  // --algo; also metrics.csv's and the columns' owner.
  std::string help;  // One line: what it is (--list).
  // Sets the algorithm's differences from LearnerConfig's defaults on
  // `scenario` (collection, budget) and its own options (config->options) to
  // its defaults there, the scenario's tuning (env::TuningOf) included.
  std::function<void(absl::string_view scenario, LearnerConfig* config)> defaults;
  // Its settings (common/base/settings.h): the rows --list prints, the flags given
  // set over config->options (errors: INVALID_ARGUMENT naming the flag), and
  // the options as "flag": value (--print_config).
  std::vector<SettingRow> settings;
  std::function<absl::Status(LearnerConfig* config)> fill_from_flags;
  std::function<void(const LearnerConfig& config, JsonObject* json)> add_json;
  // Its own columns of metrics.csv (Column::algorithm its name): what its
  // IterationStats::values hold.
  std::vector<Column> columns;
  // The algorithm for `scenario` (which must outlive it) with `config`.
  // Errors: INVALID_ARGUMENT for a configuration it refuses (options of
  // another algorithm among them); INTERNAL.
  std::function<absl::StatusOr<std::unique_ptr<Algorithm>>(const env::Scenario* scenario,
                                                          const LearnerConfig& config)>
      create;

  bool complete() const { return defaults && fill_from_flags && add_json && create; }
};

// The learner's registry (common/base/registry.h): Find's errors name --algo.
class AlgorithmRegistry : public Registry<AlgorithmEntry> {
 public:
  AlgorithmRegistry() : Registry("--algo") {}
};

// The registry of every algorithm (algorithms.def), built on first use.
const AlgorithmRegistry& Algorithms();

// The entry of algorithm `T` (T::Create(scenario, config)) whose own settings
// are an Options (held in LearnerConfig::options) declared by `table`.
template <typename T, typename Options>
AlgorithmEntry MakeAlgorithmEntry(std::string name, std::string help, const SettingTable<Options>& table,
                                  void (*defaults)(absl::string_view scenario, LearnerConfig* config),
                                  std::vector<Column> columns) {
  for (Column& column : columns) column.algorithm = name;
  return {
      .name = std::move(name),
      .help = std::move(help),
      .defaults = defaults,
      .settings = table.Rows(),
      .fill_from_flags =
          [&table](LearnerConfig* config) {
            table.Fill(&MutableOptions<Options>(config));
            return absl::OkStatus();
          },
      .add_json = [&table](const LearnerConfig& config, JsonObject* json) { table.Json(OptionsOf<Options>(config), json); },
      .columns = std::move(columns),
      .create = [](const env::Scenario* scenario,
                   const LearnerConfig& config) -> absl::StatusOr<std::unique_ptr<Algorithm>> {
        absl::StatusOr<std::unique_ptr<T>> made = T::Create(scenario, config);
        if (!made.ok()) return made.status();
        return std::unique_ptr<Algorithm>(*std::move(made));
      },
  };
}

// The defaults of a learner of `scenario` trained by `algo` (a registered
// name, "" for the default), in the order they join: LearnerConfig's, the
// scenario's tuning (env::TuningOf, beside the scenario's spec), then the
// algorithm's entry. The one definition every way of starting the learner
// resolves (the binary's flags override it, --list prints it per scenario).
// Errors: INVALID_ARGUMENT for an unknown algorithm.
absl::StatusOr<LearnerConfig> DefaultLearnerConfig(absl::string_view scenario, absl::string_view algo);

// Each folder's registration (its *_registration.cc), one per line of
// algorithms.def.
#define IMCA_ALGORITHM(name, Prefix) absl::Status Register##Prefix(AlgorithmRegistry* registry);
#include "learner/algorithms/algorithms.def"
#undef IMCA_ALGORITHM

// Helpers for an entry whose options are a T (MappoOptions, ...): the
// options `config` holds, refusing another algorithm's (INVALID_ARGUMENT).
template <typename T>
absl::StatusOr<const T*> CheckedOptions(const LearnerConfig& config) {
  IMCA_ASSIGN_OR_RETURN(const T* held, HeldOptions<T>(config.options));
  return held != nullptr ? held : &OptionsOf<T>(config);
}

}  // namespace imca::learner

#endif  // IMCA_LEARNER_ALGORITHMS_REGISTRY_H_
