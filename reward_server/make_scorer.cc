#include "reward_server/make_scorer.h"

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "reward_server/novelty/registry.h"

namespace imca::reward {

std::vector<std::string> RewardKinds() { return Novelties().Names(); }

ScorerConfig DefaultScorerConfig(const std::string& kind, absl::string_view scenario) {
  ScorerConfig config;
  if (absl::StatusOr<const NoveltyEntry*> entry = Novelties().Find(kind); entry.ok()) (*entry)->defaults(&config);
  config.beta *= env::TuningOf(scenario).bonus_scale.value_or(1.0);
  return config;
}

absl::StatusOr<std::unique_ptr<Novelty>> MakeNovelty(const std::string& kind, const env::Scenario& scenario,
                                                     const ScorerConfig& config, const std::any& options) {
  absl::StatusOr<const NoveltyEntry*> entry = Novelties().Find(kind);
  if (!entry.ok()) return entry.status();
  return (*entry)->create(scenario, config, options);
}

absl::StatusOr<std::unique_ptr<CreditScorer>> MakeScorer(const std::string& kind, const env::Scenario& scenario,
                                                         const ScorerConfig& config, const std::any& options) {
  if (!(config.beta >= 0)) return absl::InvalidArgumentError("beta must be >= 0");
  if (!(config.temperature > 0)) return absl::InvalidArgumentError("temperature must be > 0");
  auto novelty = MakeNovelty(kind, scenario, config, options);
  if (!novelty.ok()) return novelty.status();
  if (config.credit != Credit::kNone && !(*novelty)->Supports(config.credit)) {
    std::vector<std::string> served;
    for (const std::string& name : CreditNames()) {
      const Credit credit = *ParseCredit(name);
      if (credit == Credit::kNone || (*novelty)->Supports(credit)) served.push_back(name);
    }
    return absl::InvalidArgumentError(absl::StrCat("credit '", CreditName(config.credit),
                                                   "' is not served by reward '", kind, "' (it serves: ",
                                                   absl::StrJoin(served, ", "), ")"));
  }
  return std::make_unique<CreditScorer>(*std::move(novelty), config, scenario.num_agents());
}

}  // namespace imca::reward
