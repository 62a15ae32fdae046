#include "learner/learner_flags.h"

#include <optional>
#include <utility>

#include "absl/flags/flag.h"
#include "absl/strings/str_cat.h"
#include "common/base/json.h"
#include "common/base/status_macros.h"
#include "learner/algorithms/registry.h"

IMCA_LEARNER_SETTINGS(IMCA_SETTING_FLAG)
ABSL_FLAG(std::string, algo, "", "the training algorithm, one of --list's algos (default: the first, mappo)");
namespace {
constexpr char kMaxBatchMbHelp[] =
    "cap on an iteration's feature arrays in MB (batch_steps and unroll sizes over it are rejected)";
}  // namespace
ABSL_FLAG(std::optional<int64_t>, max_batch_mb, std::nullopt, kMaxBatchMbHelp);

namespace imca::learner {

namespace {

IMCA_SETTING_TABLE(SharedSettings, LearnerConfig, IMCA_LEARNER_SETTINGS)

}  // namespace

std::vector<SettingRow> LearnerSettingRows() {
  std::vector<SettingRow> rows = SharedSettings().Rows();
  rows.insert(rows.begin(), {"algo", "enum", "the training algorithm", Algorithms().Names(), ""});
  rows.push_back(MakeSettingRow<int64_t>("max_batch_mb", kMaxBatchMbHelp));
  return Algorithms().AllSettings(std::move(rows));
}

absl::StatusOr<LearnerConfig> LearnerConfigFromFlags(absl::string_view scenario) {
  IMCA_ASSIGN_OR_RETURN(const AlgorithmEntry* entry, Algorithms().Find(absl::GetFlag(FLAGS_algo)));
  IMCA_ASSIGN_OR_RETURN(LearnerConfig config, DefaultLearnerConfig(scenario, entry->name));
  SharedSettings().Fill(&config);
  if (const std::optional<int64_t> mb = absl::GetFlag(FLAGS_max_batch_mb)) {
    if (*mb < 1 || *mb > (int64_t{1} << 30)) return absl::InvalidArgumentError("--max_batch_mb must be in [1, 2^30]");
    config.max_batch_bytes = *mb * 1000 * 1000;
  }
  IMCA_RETURN_IF_ERROR(
      RefuseOthersSettings(entry->settings, Algorithms().OthersSettings(entry), "--algo", entry->name));
  IMCA_RETURN_IF_ERROR(entry->fill_from_flags(&config));
  return config;
}

std::string LearnerConfigJson(const LearnerConfig& config) {
  JsonObject json;
  json.Add("algo", config.algo);
  SharedSettings().Json(config, &json);
  json.Add("max_batch_mb", config.max_batch_bytes / 1000000);
  if (absl::StatusOr<const AlgorithmEntry*> entry = Algorithms().Find(config.algo); entry.ok()) {
    (*entry)->add_json(config, &json);
  }
  return json.Text();
}

}  // namespace imca::learner
