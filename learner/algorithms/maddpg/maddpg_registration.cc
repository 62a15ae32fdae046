// MADDPG's entry in the algorithm registry: its settings (maddpg_options.h)
// as flags, defaults, metrics columns and factory.
#include <memory>
#include <utility>

#include "base/settings.h"
#include "base/status_macros.h"
#include "learner/algorithms/maddpg/maddpg.h"
#include "learner/algorithms/registry.h"

IMCA_MADDPG_SETTINGS(IMCA_SETTING_FLAG)

namespace imca::learner {

namespace {

// Off-policy: it learns from a replay of any age, so collection is
// asynchronous.
void Defaults(absl::string_view, LearnerConfig* learner) {
  MutableOptions<MaddpgConfig>(learner);
  learner->synchronous = false;
}

absl::Status FillFromFlags(LearnerConfig* learner) {
  MaddpgConfig* config = &MutableOptions<MaddpgConfig>(learner);
  IMCA_MADDPG_SETTINGS(IMCA_SETTING_FILL)
  return absl::OkStatus();
}

void AddJson(const LearnerConfig& learner, JsonObject* json) {
  const MaddpgConfig& config = OptionsOf<MaddpgConfig>(learner);
  IMCA_MADDPG_SETTINGS(IMCA_SETTING_JSON)
}

std::vector<SettingRow> Rows() {
  std::vector<SettingRow> rows;
  IMCA_MADDPG_SETTINGS(IMCA_SETTING_ROW)
  return rows;
}

// MADDPG's own columns of metrics.csv: what Maddpg::Train's values hold.
std::vector<Column> Columns() {
  return {
      {"actor_loss", "%.6g", 1, "The actors' loss, -mean Q_i plus the logit regulariser, mean over the iteration's "
       "gradient steps.", nullptr, Export::kGauge, "imca_learner_actor_loss"},
      {"critic_loss", "%.6g", 1, "The critics' squared TD error, mean over the iteration's gradient steps.", nullptr,
       Export::kGauge, "imca_learner_critic_loss"},
      {"replay_size", "%.0f", 1, "Transitions in the replay buffer.", nullptr, Export::kGauge,
       "imca_learner_replay_transitions"},
  };
}

}  // namespace

absl::Status RegisterMaddpg(AlgorithmRegistry* registry) {
  return registry->Add({
      .name = "maddpg",
      .help = "off-policy MADDPG for discrete actions: a replay buffer, a critic per agent (docs/learner.md)",
      .defaults = Defaults,
      .settings = Rows(),
      .fill_from_flags = FillFromFlags,
      .add_json = AddJson,
      .columns = Columns(),
      .create = [](const env::Scenario* scenario,
                   const LearnerConfig& config) -> absl::StatusOr<std::unique_ptr<Algorithm>> {
        IMCA_ASSIGN_OR_RETURN(std::unique_ptr<Maddpg> algorithm, Maddpg::Create(scenario, config));
        return std::unique_ptr<Algorithm>(std::move(algorithm));
      },
  });
}

}  // namespace imca::learner
