// CMAE's entry in the algorithm registry: its settings (cmae_options.h)
// as flags, defaults, metrics columns and factory.
#include "common/base/settings.h"
#include "common/protocol/policy_table.h"
#include "learner/algorithms/cmae/cmae.h"
#include "learner/algorithms/registry.h"

IMCA_CMAE_SETTINGS(IMCA_SETTING_FLAG)

namespace imca::learner {

namespace {

IMCA_SETTING_TABLE(Settings, CmaeConfig, IMCA_CMAE_SETTINGS)

// CMAE's own loop: one environment, the tables updated at each episode's
// end and acted with from the next (one actor acting a 300-step unroll, its
// episode, per version), for at most cmae_episodes episodes of 300 steps.
void Defaults(absl::string_view, LearnerConfig* learner) {
  const CmaeConfig& options = MutableOptions<CmaeConfig>(learner);
  learner->actors = 1;
  learner->batch_steps = kCmaeEpisodeSteps;
  learner->budget_steps = options.total_episodes * kCmaeEpisodeSteps;
}

// CMAE's own columns of metrics.csv: what Cmae::Train's values hold.
std::vector<Column> Columns() {
  return {
      {"cmae_episodes", "%.0f", 1, "Episodes CMAE has finished (each chose a goal and refitted the tables).", nullptr,
       Export::kGauge, "imca_learner_cmae_episodes"},
      {"cmae_exploit_weight", "%.4f", 1, "Weight of the exploitation tables in acting, episodes / --cmae_episodes.",
       nullptr, Export::kGauge, "imca_learner_cmae_exploit_weight"},
      {"cmae_goals_reached", "%.4f", 1, "Share of the iteration's goals whose way in was in the replay.", nullptr,
       Export::kCsvOnly, nullptr},
      {"cmae_space_vars", "%.0f", 1, "Variables of the restricted space goals are chosen in.", nullptr,
       Export::kGauge, "imca_learner_cmae_space_variables"},
      {"cmae_space_entropy", "%.6g", 1, "Normalised entropy of that space's counts.", nullptr, Export::kCsvOnly,
       nullptr},
      {"cmae_exploit_states", "%.0f", 1, "Joint states where agent 1's exploitation table is not all 0.", nullptr,
       Export::kGauge, "imca_learner_cmae_exploit_states"},
      {"cmae_replay", "%.0f", 1, "Transitions in CMAE's replay.", nullptr, Export::kGauge,
       "imca_learner_cmae_replay_transitions"},
  };
}

}  // namespace

absl::Status RegisterCmae(AlgorithmRegistry* registry) {
  return registry->Add(MakeAlgorithmEntry<Cmae>("cmae", "tabular CMAE as its released gridworld code runs it (docs/baselines.md)", Settings(), Defaults, Columns()));
}

}  // namespace imca::learner
