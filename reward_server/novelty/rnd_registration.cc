// RND's entry in the novelty registry: its settings (rnd_novelty.h) as
// flags, its defaults and factory.
#include "common/base/settings.h"
#include "reward_server/novelty/registry.h"
#include "reward_server/novelty/rnd_novelty.h"

IMCA_RND_SETTINGS(IMCA_SETTING_FLAG)

namespace imca::reward {

namespace {

IMCA_SETTING_TABLE(Settings, RndConfig, IMCA_RND_SETTINGS)

}  // namespace

absl::Status RegisterRnd(NoveltyRegistry* registry) {
  return registry->Add(MakeNoveltyEntry<RndConfig>(
      "rnd", "random network distillation on the joint state and action (paper eq. 6)", &Settings(),
      GlobalBonusDefaults, CreateLearned<RndNovelty, RndConfig>));
}

}  // namespace imca::reward
