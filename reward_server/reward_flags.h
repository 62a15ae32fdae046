#ifndef IMCA_REWARD_SERVER_REWARD_FLAGS_H_
#define IMCA_REWARD_SERVER_REWARD_FLAGS_H_

#include <any>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "common/base/json.h"
#include "common/base/settings.h"
#include "reward_server/credit.h"

namespace imca::reward {

// The reward server's scoring settings as flags: --reward, the shared ones
// (IMCA_SCORER_SETTINGS) and every registered kind's (its entry). The only
// reader of those flags.

// What the server scores with: the kind, the shared settings, the kind's own.
struct RewardConfig {
  std::string kind;
  ScorerConfig scorer;
  std::any options;  // The kind's options type (novelty/registry.h).
};

// Every setting, --reward and the shared ones first, then the kinds' (owner:
// the kinds that read it, comma-separated): what --list prints.
std::vector<SettingRow> RewardSettingRows();

// The configuration the flags resolve on `scenario`: DefaultScorerConfig for
// it and --reward, then every setting given (a kind's settings set its own
// options). Errors: INVALID_ARGUMENT naming the flag, a setting of another
// kind among them.
absl::StatusOr<RewardConfig> RewardConfigFromFlags(absl::string_view scenario);

// The kind's defaults on `scenario` (--list).
RewardConfig DefaultRewardConfig(const std::string& kind, absl::string_view scenario);

// Adds the configuration as flag name: value (the kind, the shared settings,
// the kind's own) to `json`: passed back as flags, it resolves the same.
void AddRewardConfigJson(const RewardConfig& config, JsonObject* json);

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_REWARD_FLAGS_H_
