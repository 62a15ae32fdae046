// Count's entry in the novelty registry: no settings of its own.
#include <memory>

#include "reward_server/novelty/count_novelty.h"
#include "reward_server/novelty/registry.h"

namespace imca::reward {

namespace {

struct NoOptions {};

absl::StatusOr<std::unique_ptr<Novelty>> Create(const env::Scenario& scenario, const ScorerConfig& config,
                                                const NoOptions&) {
  return std::unique_ptr<Novelty>(std::make_unique<CountNovelty>(scenario, config));
}

}  // namespace

absl::Status RegisterCount(NoveltyRegistry* registry) {
  return registry->Add(MakeNoveltyEntry<NoOptions>(
      "count", "visit counts of the joint state and action: N = 1 / sqrt(C + 1) (docs/credit.md)", nullptr,
      GlobalBonusDefaults, Create));
}

}  // namespace imca::reward
