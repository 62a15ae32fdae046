#include "learner/algorithms/registry.h"

#include <cstdio>
#include <cstdlib>
#include <utility>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"

namespace imca::learner {

namespace {

// Every algorithm of algorithms.def, in its order.
AlgorithmRegistry Build() {
  AlgorithmRegistry registry;
  const auto add = [&registry](absl::Status added, const char* name) {
    // The entry is named as algorithms.def names it (the actors' list).
    if (added.ok() && registry.entries().back().name != name) {
      added = absl::InternalError(absl::StrCat("Register* of '", name, "' registered '",
                                               registry.entries().back().name, "'"));
    }
    if (!added.ok()) {  // A programming error: fail at the first use, loudly.
      std::fprintf(stderr, "learner: algorithm registry: %s\n", std::string(added.message()).c_str());
      std::abort();
    }
  };
#define IMCA_ALGORITHM(name, Prefix) add(Register##Prefix(&registry), #name);
#include "learner/algorithms/algorithms.def"
#undef IMCA_ALGORITHM
  return registry;
}

}  // namespace

const AlgorithmRegistry& Algorithms() {
  static const AlgorithmRegistry* const kRegistry = new AlgorithmRegistry(Build());
  return *kRegistry;
}

absl::StatusOr<LearnerConfig> DefaultLearnerConfig(absl::string_view scenario, absl::string_view algo) {
  IMCA_ASSIGN_OR_RETURN(const AlgorithmEntry* entry, Algorithms().Find(algo));
  LearnerConfig config;
  config.algo = entry->name;
  config.batch_steps = env::TuningOf(scenario).batch_steps.value_or(config.batch_steps);
  entry->defaults(scenario, &config);
  return config;
}

}  // namespace imca::learner
