#include "reward_server/reward_flags.h"

#include <algorithm>
#include <optional>
#include <utility>

#include "absl/flags/flag.h"
#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "reward_server/credit/registry.h"
#include "reward_server/make_scorer.h"
#include "reward_server/novelty/registry.h"

IMCA_SCORER_SETTINGS(IMCA_SETTING_FLAG)
ABSL_FLAG(std::string, reward, "", "reward kind, one of --list's rewards (default: the first, count)");
ABSL_FLAG(std::string, credit, "",
          "credit rule: how the global bonus becomes per-agent bonuses, one of --list's credits (default: the "
          "reward kind's)");

namespace imca::reward {

namespace {

IMCA_SETTING_TABLE(SharedSettings, ScorerConfig, IMCA_SCORER_SETTINGS)

}  // namespace

std::vector<SettingRow> RewardSettingRows() {
  std::vector<SettingRow> rows = SharedSettings().Rows();
  rows.insert(rows.begin(), {"credit", "enum", "credit rule: how the global bonus becomes per-agent bonuses",
                             CreditRules().Names(), ""});
  rows.insert(rows.begin(), {"reward", "enum", "reward kind: the global novelty", Novelties().Names(), ""});
  return Novelties().AllSettings(std::move(rows));
}

RewardConfig DefaultRewardConfig(const std::string& kind, absl::string_view scenario) {
  return {kind, DefaultScorerConfig(kind, scenario), {}};
}

absl::StatusOr<RewardConfig> RewardConfigFromFlags(absl::string_view scenario) {
  IMCA_ASSIGN_OR_RETURN(const NoveltyEntry* entry, Novelties().Find(absl::GetFlag(FLAGS_reward)));
  RewardConfig config = DefaultRewardConfig(entry->name, scenario);
  if (const std::string credit = absl::GetFlag(FLAGS_credit); !credit.empty()) {
    IMCA_ASSIGN_OR_RETURN(const CreditRuleEntry* rule, CreditRules().Find(credit));
    config.scorer.credit = rule->name;
  }
  SharedSettings().Fill(&config.scorer);
  IMCA_RETURN_IF_ERROR(
      RefuseOthersSettings(entry->settings, Novelties().OthersSettings(entry), "--reward", entry->name));
  entry->fill_from_flags(&config.options);
  return config;
}

void AddRewardConfigJson(const RewardConfig& config, JsonObject* json) {
  json->Add("reward", config.kind);
  json->Add("credit", config.scorer.credit);
  SharedSettings().Json(config.scorer, json);
  if (absl::StatusOr<const NoveltyEntry*> entry = Novelties().Find(config.kind); entry.ok()) {
    (*entry)->add_json(config.options, json);
  }
}

}  // namespace imca::reward
