#ifndef IMCA_LEARNER_LEARNER_FLAGS_H_
#define IMCA_LEARNER_LEARNER_FLAGS_H_

#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "common/base/settings.h"
#include "learner/learner_config.h"

namespace imca::learner {

// The learner's training settings as flags: the shared ones
// (IMCA_LEARNER_SETTINGS), --algo, --max_batch_mb and every registered
// algorithm's (its entry). The only reader of those flags.

// Every setting, the shared ones first, then each algorithm's (owner: its
// name): what --list prints.
std::vector<SettingRow> LearnerSettingRows();

// The configuration the flags resolve for `scenario`: DefaultLearnerConfig
// for it and --algo, then every setting given (an algorithm's settings
// set its own options). Errors: INVALID_ARGUMENT naming the flag, a setting
// of another algorithm among them.
absl::StatusOr<LearnerConfig> LearnerConfigFromFlags(absl::string_view scenario);

// The training configuration as flag name: value, the shared settings and
// its algorithm's (what --print_config prints and --list gives per
// scenario): passed back as flags, it resolves to the same configuration.
std::string LearnerConfigJson(const LearnerConfig& config);

}  // namespace imca::learner

#endif  // IMCA_LEARNER_LEARNER_FLAGS_H_
