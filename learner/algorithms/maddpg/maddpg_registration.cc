// MADDPG's entry in the algorithm registry: its settings (maddpg_options.h)
// as flags, defaults, metrics columns and factory.
#include "common/base/settings.h"
#include "learner/algorithms/maddpg/maddpg.h"
#include "learner/algorithms/registry.h"

IMCA_MADDPG_SETTINGS(IMCA_SETTING_FLAG)

namespace imca::learner {

namespace {

IMCA_SETTING_TABLE(Settings, MaddpgConfig, IMCA_MADDPG_SETTINGS)

// Off-policy: it learns from a replay of any age, so collection is
// asynchronous.
void Defaults(absl::string_view, LearnerConfig* learner) {
  MutableOptions<MaddpgConfig>(learner);
  learner->synchronous = false;
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
  return registry->Add(MakeAlgorithmEntry<Maddpg>("maddpg", "off-policy MADDPG for discrete actions: a replay buffer, a critic per agent (docs/learner.md)", Settings(), Defaults, Columns()));
}

}  // namespace imca::learner
