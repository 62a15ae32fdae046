#include "learner/algorithms/registry.h"

#include <cstdio>
#include <cstdlib>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "base/status_macros.h"
#include "learner/algorithms/cmae/cmae.h"
#include "learner/algorithms/maddpg/maddpg.h"
#include "learner/algorithms/mappo/mappo.h"

namespace imca::learner {

namespace {

// Every algorithm, the first the default: one line each.
AlgorithmRegistry Build() {
  AlgorithmRegistry registry;
  for (const absl::Status& added : {
           RegisterMappo(&registry),
           RegisterMaddpg(&registry),
           RegisterCmae(&registry),
       }) {
    if (!added.ok()) {  // A programming error: fail at the first use, loudly.
      std::fprintf(stderr, "learner: algorithm registry: %s\n", std::string(added.message()).c_str());
      std::abort();
    }
  }
  return registry;
}

}  // namespace

absl::Status AlgorithmRegistry::Add(AlgorithmEntry entry) {
  if (entry.name.empty()) return absl::InvalidArgumentError("an algorithm needs a name");
  for (const AlgorithmEntry& e : entries_) {
    if (e.name == entry.name) {
      return absl::InvalidArgumentError(absl::StrCat("algorithm '", entry.name, "' is registered twice"));
    }
  }
  if (!entry.defaults || !entry.fill_from_flags || !entry.add_json || !entry.create) {
    return absl::InvalidArgumentError(absl::StrCat("algorithm '", entry.name, "' lacks a hook"));
  }
  for (SettingRow& row : entry.settings) row.owner = entry.name;
  for (Column& column : entry.columns) column.algorithm = entry.name;
  entries_.push_back(std::move(entry));
  return absl::OkStatus();
}

absl::StatusOr<const AlgorithmEntry*> AlgorithmRegistry::Find(absl::string_view name) const {
  if (name.empty() && !entries_.empty()) return &entries_.front();
  for (const AlgorithmEntry& entry : entries_) {
    if (entry.name == name) return &entry;
  }
  std::vector<std::string> names = Names();
  std::string choices = names.empty() ? "none registered" : names.back();
  if (names.size() > 1) {
    names.pop_back();
    choices = absl::StrCat(absl::StrJoin(names, ", "), " or ", choices);
  }
  return absl::InvalidArgumentError(absl::StrCat("--algo: '", name, "' is not ", choices));
}

std::vector<std::string> AlgorithmRegistry::Names() const {
  std::vector<std::string> names;
  for (const AlgorithmEntry& entry : entries_) names.push_back(entry.name);
  return names;
}

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
