// SF's entry in the novelty registry: its settings (sf_novelty.h) as flags,
// its defaults and factory.
#include "common/base/settings.h"
#include "reward_server/novelty/registry.h"
#include "reward_server/novelty/sf_novelty.h"

IMCA_SF_SETTINGS(IMCA_SETTING_FLAG)

namespace imca::reward {

namespace {

IMCA_SETTING_TABLE(Settings, SfConfig, IMCA_SF_SETTINGS)

}  // namespace

absl::Status RegisterSf(NoveltyRegistry* registry) {
  return registry->Add(MakeNoveltyEntry<SfConfig>(
      "sf", "successor-feature control of the joint state (paper eq. 7, 11-13)", &Settings(), GlobalBonusDefaults,
      CreateLearned<SfNovelty, SfConfig>));
}

}  // namespace imca::reward
