// EITI's and EDTI's entries in the novelty registry: their one settings
// table (influence_novelty.h) as flags, their defaults and factories.
#include <memory>

#include "common/base/settings.h"
#include "reward_server/novelty/influence_novelty.h"
#include "reward_server/novelty/registry.h"

IMCA_INFLUENCE_SETTINGS(IMCA_SETTING_FLAG)

namespace imca::reward {

namespace {

IMCA_SETTING_TABLE(Settings, InfluenceConfig, IMCA_INFLUENCE_SETTINGS)

// Per-agent by construction (docs/baselines.md): eta and beta_t set the scale.
void InfluenceDefaults(ScorerConfig* config) {
  config->credit = "independent";
  config->beta = 1.0;
}

template <bool kEdti>
absl::StatusOr<std::unique_ptr<Novelty>> Create(const env::Scenario& scenario, const ScorerConfig& config,
                                                const InfluenceConfig& options) {
  if (scenario.num_actions() > 8) {
    return absl::InvalidArgumentError("eiti/edti: at most 8 actions (their count keys hold 3 bits)");
  }
  if (!(options.eta >= 0)) return absl::InvalidArgumentError("eta must be >= 0");
  if (!(options.beta_t >= 0)) return absl::InvalidArgumentError("beta_t must be >= 0");
  InfluenceConfig influence = options;
  influence.edti = kEdti;
  return std::unique_ptr<Novelty>(std::make_unique<InfluenceNovelty>(scenario, config, influence));
}

}  // namespace

absl::Status RegisterInfluence(NoveltyRegistry* registry) {
  absl::Status added = registry->Add(MakeNoveltyEntry<InfluenceConfig>(
      "eiti", "EITI: decentralised curiosity plus the summed influence on the others (Wang et al. 2020)",
      &Settings(), InfluenceDefaults, Create<false>));
  if (!added.ok()) return added;
  return registry->Add(MakeNoveltyEntry<InfluenceConfig>(
      "edti", "EDTI: decentralised curiosity; the learner adds the value of interaction (--edti)", &Settings(),
      InfluenceDefaults, Create<true>));
}

}  // namespace imca::reward
