// MAPPO's entry in the algorithm registry: its settings (mappo_options.h)
// as flags, defaults, metrics columns and factory.
#include <utility>

#include "common/base/enum_names.h"
#include "common/base/settings.h"
#include "common/env/env.h"
#include "learner/algorithms/mappo/mappo.h"
#include "learner/algorithms/registry.h"

IMCA_MAPPO_SETTINGS(IMCA_SETTING_FLAG)

namespace imca::learner {

namespace {

constexpr EnumName<CriticInput> kCriticInputNames[] = {{CriticInput::kState, "state"},
                                                       {CriticInput::kJointObs, "joint_obs"}};
constexpr EnumName<ValueNorm> kValueNormNames[] = {{ValueNorm::kBatch, "batch"}, {ValueNorm::kEma, "ema"}};

IMCA_SETTING_TABLE(Settings, MappoOptions, IMCA_MAPPO_SETTINGS)

// The scenario's tuning of PPO (env::TuningOf, beside the scenario's spec).
void Defaults(absl::string_view scenario, LearnerConfig* learner) {
  MappoOptions& options = MutableOptions<MappoOptions>(learner);
  const env::ScenarioTuning& tuning = env::TuningOf(scenario);
  options.ppo.learning_rate = tuning.learning_rate.value_or(options.ppo.learning_rate);
  options.ppo.separate_optimizers = tuning.separate_optimizers.value_or(options.ppo.separate_optimizers);
}

// --edti gives the critic its third head.
absl::Status EdtiHeads(LearnerConfig* learner) {
  MappoOptions& options = MutableOptions<MappoOptions>(learner);
  if (options.edti) {
    if (options.ppo.value_heads == 1) {
      return absl::InvalidArgumentError("--value_heads 1 cannot be used with --edti (it needs 3)");
    }
    options.ppo.value_heads = 3;
  }
  return absl::OkStatus();
}

// MAPPO's own columns of metrics.csv: what Mappo::Train's values hold.
std::vector<Column> Columns() {
  return {
      {"policy_loss", "%.6g", 1, "PPO's clipped surrogate loss of the iteration.", nullptr, Export::kGauge,
       "imca_learner_policy_loss"},
      {"value_loss", "%.6g", 1, "The critic's squared error of the iteration (summed over its heads).", nullptr,
       Export::kGauge, "imca_learner_value_loss"},
      {"approx_kl", "%.6g", 1, "Approximate KL divergence of the update.", nullptr, Export::kGauge,
       "imca_learner_approx_kl"},
      {"clip_fraction", "%.4f", 1, "Share of samples whose ratio was clipped.", nullptr, Export::kGauge,
       "imca_learner_clip_fraction_ratio"},
      {"behaviour_kl", "%.6g", 1, "KL divergence of the behaviour policy from the proximal one.", nullptr,
       Export::kGauge, "imca_learner_behaviour_kl"},
      {"voi_reward", "%.6g", 1, "EDTI's mean value-of-interaction reward (--edti).", nullptr, Export::kCsvOnly,
       nullptr},
  };
}

}  // namespace

std::vector<std::string> SettingChoices(CriticInput) { return Names(kCriticInputNames); }
bool AbslParseFlag(absl::string_view text, CriticInput* input, std::string* error) {
  return ParseFlagName(text, kCriticInputNames, input, error);
}
std::string AbslUnparseFlag(CriticInput input) { return NameOf(input, kCriticInputNames); }

std::vector<std::string> SettingChoices(ValueNorm) { return Names(kValueNormNames); }
bool AbslParseFlag(absl::string_view text, ValueNorm* norm, std::string* error) {
  return ParseFlagName(text, kValueNormNames, norm, error);
}
std::string AbslUnparseFlag(ValueNorm norm) { return NameOf(norm, kValueNormNames); }

std::vector<std::string> SettingChoices(PpoObjective) { return PpoObjectiveNames(); }
bool AbslParseFlag(absl::string_view text, PpoObjective* objective, std::string* error) {
  absl::StatusOr<PpoObjective> parsed = ParsePpoObjective(std::string(text));
  if (!parsed.ok()) {
    *error = std::string(parsed.status().message());
    return false;
  }
  *objective = *parsed;
  return true;
}
std::string AbslUnparseFlag(PpoObjective objective) { return PpoObjectiveName(objective); }

absl::Status RegisterMappo(AlgorithmRegistry* registry) {
  AlgorithmEntry entry = MakeAlgorithmEntry<Mappo>(
      "mappo", "on-policy multi-agent PPO: a shared actor, a centralised critic (docs/learner.md)", Settings(),
      Defaults, Columns());
  entry.fill_from_flags = [fill = std::move(entry.fill_from_flags)](LearnerConfig* config) {
    absl::Status filled = fill(config);
    return filled.ok() ? EdtiHeads(config) : filled;
  };
  return registry->Add(std::move(entry));
}

}  // namespace imca::learner
