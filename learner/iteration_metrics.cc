#include "learner/iteration_metrics.h"

#include <cstdio>
#include <limits>
#include <utility>

#include "absl/strings/str_cat.h"
#include "learner/algorithms/registry.h"

namespace imca::learner {

using R = IterationRecord;

namespace {

// Every algorithm's columns (each algorithm's own are in its registry entry).
std::vector<Column> CommonColumns() {
  return {
      {"iteration", "%.0f", 1, "Training iterations completed.", &R::iteration, Export::kCumulative,
       "imca_learner_iterations_total"},
      {"env_steps", "%.0f", 1, "Joint environment steps trained on.", &R::env_steps, Export::kCumulative,
       "imca_learner_env_steps_total"},
      {"wall_seconds", "%.3f", 1, "Seconds of training, earlier runs of a resumed one included.", &R::wall_seconds,
       Export::kCsvOnly, nullptr, "", true},
      {"env_steps_per_sec", "%.1f", 1, "env_steps / wall_seconds.",
       &R::env_steps_per_sec, Export::kCsvOnly, nullptr, "", true},
      {"success_rate", "%.4f", 1, "Success rate over the recent evaluation episodes (window success_episodes).",
       &R::success_rate, Export::kGauge, "imca_learner_eval_success_ratio"},
      {"train_success_rate", "%.4f", 1, "Success rate over the recent training episodes.", &R::train_success_rate,
       Export::kGauge, "imca_learner_train_success_ratio"},
      {"episode_return", "%.4f", 1, "Mean team return of the recent training episodes.", &R::episode_return,
       Export::kGauge, "imca_learner_episode_return"},
      {"intrinsic_reward", "%.6g", 1, "Mean intrinsic reward per agent-step of the iteration's batch.",
       &R::intrinsic_reward, Export::kGauge, "imca_learner_intrinsic_reward"},
      {"share_max", "%.4f", 1, "Mean over transitions of the largest credit share max_a p^a.", &R::share_max,
       Export::kGauge, "imca_learner_credit_share_max_ratio"},
      {"policy_version", "%.0f", 1, "Version of the policy published after the iteration.", &R::policy_version,
       Export::kGauge, "imca_learner_policy_version"},
      {"policy_lag", "%.3f", 1, "Mean versions between an unroll's acting policy and the trained one.",
       &R::policy_lag, Export::kCsvOnly, nullptr},
      {"dropped_stale", "%.0f", 1, "Unrolls dropped as stale so far.", &R::dropped_stale, Export::kCsvOnly, nullptr},
      {"ms_wait", "%.2f", 1e3, "Milliseconds the iteration waited for unrolls.",
       &R::wait, Export::kCsvOnly, nullptr, "", true},
      {"ms_featurise", "%.2f", 1e3, "Milliseconds of featurising the batch (on the pushing threads).", &R::featurise,
       Export::kCsvOnly, nullptr, "", true},
      {"ms_values", "%.2f", 1e3, "Milliseconds of value predictions.",
       &R::values, Export::kCsvOnly, nullptr, "", true},
      {"ms_gae", "%.2f", 1e3, "Milliseconds of GAE.", &R::gae, Export::kCsvOnly, nullptr, "", true},
      {"ms_copy", "%.2f", 1e3, "Milliseconds of copying into the batch.",
       &R::copy, Export::kCsvOnly, nullptr, "", true},
      {"ms_prepare", "%.2f", 1e3, "Milliseconds of preparing minibatches.",
       &R::prepare, Export::kCsvOnly, nullptr, "", true},
      {"ms_forward", "%.2f", 1e3, "Milliseconds of forward passes.",
       &R::forward, Export::kCsvOnly, nullptr, "", true},
      {"ms_backward", "%.2f", 1e3, "Milliseconds of backward passes.",
       &R::backward, Export::kCsvOnly, nullptr, "", true},
      {"ms_optimizer", "%.2f", 1e3, "Milliseconds of optimiser steps.",
       &R::optimizer, Export::kCsvOnly, nullptr, "", true},
      {"ms_publish", "%.2f", 1e3, "Milliseconds of publishing the policy.",
       &R::publish, Export::kCsvOnly, nullptr, "", true},
      {"global_reward", "%.6g", 1, "Mean global intrinsic reward R_i per transition.", &R::global_reward,
       Export::kGauge, "imca_learner_global_reward"},
      {"contribution_abs", "%.6g", 1, "Mean |r^a| (or d^a) per agent-step.", &R::contribution_abs, Export::kCsvOnly,
       nullptr},
      {"success_episodes", "%.0f", 1, "Evaluation episodes success_rate is over.", &R::success_episodes,
       Export::kCsvOnly, nullptr},
      {"train_success_episodes", "%.0f", 1, "Training episodes train_success_rate is over.",
       &R::train_success_episodes, Export::kCsvOnly, nullptr},
      {"entropy", "%.6g", 1, "Mean entropy of the acting policies in nats.", &R::entropy, Export::kGauge,
       "imca_learner_entropy_nats"},
      {"updates", "%.0f", 1, "Gradient steps of the iteration.", &R::updates, Export::kIncrement,
       "imca_learner_gradient_steps_total"},
  };
}

}  // namespace

const std::vector<Column>& IterationColumns() {
  static const std::vector<Column>* const kColumns = [] {
    std::vector<Column> columns = CommonColumns();
    for (const AlgorithmEntry& entry : Algorithms().entries()) {
      columns.insert(columns.end(), entry.columns.begin(), entry.columns.end());
    }
    return new std::vector<Column>(std::move(columns));
  }();
  return *kColumns;
}

std::vector<Column> RunColumns(const std::string& algorithm) {
  std::vector<Column> run;
  for (const Column& c : IterationColumns()) {
    if (c.algorithm.empty() || algorithm == c.algorithm) run.push_back(c);
  }
  return run;
}

std::vector<std::string> AlgorithmColumnNames(const std::string& algorithm) {
  std::vector<std::string> names;
  for (const Column& c : IterationColumns()) {
    if (!c.algorithm.empty() && algorithm == c.algorithm) names.push_back(c.name);
  }
  return names;
}

std::string CsvHeader(const std::string& algorithm, int num_agents) {
  std::string header;
  for (const Column& c : RunColumns(algorithm)) absl::StrAppend(&header, header.empty() ? "" : ",", c.name);
  for (int a = 1; a <= num_agents; ++a) absl::StrAppend(&header, ",share_", a);
  return header;
}

namespace {

// `format` (one printf conversion of a double) of `value`, at any length.
std::string Cell(const char* format, double value) {
  std::string cell(std::snprintf(nullptr, 0, format, value), '\0');
  std::snprintf(cell.data(), cell.size() + 1, format, value);
  return cell;
}

// The value of column `c` in `record`: nan for an own column it lacks (an
// iteration whose batch the algorithm refused, or a restored learner's first
// record), in the CSV and the gauge alike.
double Value(const Column& c, const IterationRecord& record) {
  if (c.value != nullptr) return record.*c.value;
  const auto it = record.algorithm.find(c.name);
  return it != record.algorithm.end() ? it->second : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace

std::string CsvRow(const std::string& algorithm, const IterationRecord& record) {
  std::string row;
  for (const Column& c : RunColumns(algorithm)) {
    absl::StrAppend(&row, row.empty() ? "" : ",", Cell(c.format, Value(c, record) * c.scale));
  }
  for (double p : record.shares) absl::StrAppend(&row, ",", Cell("%.4f", p));
  return row;
}

IterationExporter::IterationExporter(metrics::Registry* registry, const std::string& algorithm)
    : columns_(RunColumns(algorithm)),
      gauges_(columns_.size()),
      counters_(columns_.size()),
      cumulative_(columns_.size()) {
  for (size_t i = 0; i < columns_.size(); ++i) {
    const Column& c = columns_[i];
    switch (c.exported) {
      case Export::kCsvOnly:
        break;
      case Export::kGauge:
        gauges_[i] = &registry->AddGauge({c.family, metrics::Type::kGauge, c.help});
        break;
      case Export::kIncrement:
        counters_[i] = &registry->AddCounter({c.family, metrics::Type::kCounter, c.help});
        break;
      case Export::kCumulative: {
        // Set, not added to: a value the learner keeps (and restores).
        std::atomic<double>* value = &cumulative_[i];
        registry->AddCallback({c.family, metrics::Type::kCounter, c.help},
                              [value] { return value->load(std::memory_order_relaxed); });
        break;
      }
    }
  }
}

void IterationExporter::Publish(const IterationRecord& record) {
  for (size_t i = 0; i < columns_.size(); ++i) {
    const double v = Value(columns_[i], record);
    if (gauges_[i] != nullptr) gauges_[i]->Set(v);
    if (counters_[i] != nullptr) counters_[i]->Increment(v);
    if (columns_[i].exported == Export::kCumulative) cumulative_[i].store(v, std::memory_order_relaxed);
  }
}

}  // namespace imca::learner
