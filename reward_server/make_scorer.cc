#include "reward_server/make_scorer.h"

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "nn/threads.h"
#include "reward_server/novelty/count_novelty.h"

namespace imca::reward {

std::vector<std::string> RewardKinds() { return {"count", "rnd", "sf", "eiti", "edti"}; }

ScorerConfig DefaultScorerConfig(const std::string& kind, absl::string_view scenario) {
  ScorerConfig config;
  if (kind == "count" || kind == "rnd" || kind == "sf") {
    // The global bonuses: half the novelty, split by IMCA (the scale of every
    // row of docs/results.md).
    config.credit = Credit::kImca;
    config.beta = 0.5;
  } else if (kind == "eiti" || kind == "edti") {
    // Per-agent by construction (BASELINES.md 1): eta and beta_t scale them.
    config.credit = Credit::kIndependent;
    config.beta = 1.0;
  }
  config.beta *= env::TuningOf(scenario).bonus_scale.value_or(1.0);
  return config;
}

absl::StatusOr<std::unique_ptr<Novelty>> MakeNovelty(const std::string& kind, const env::Scenario& scenario,
                                                     const ScorerConfig& config, const RewardKindConfig& kinds) {
  if (kind == "count") return std::make_unique<CountNovelty>(scenario, config);
  if (kind == "rnd" || kind == "sf") nn::SetTorchThreads(kinds.threads);  // Once per process.
  if (kind == "rnd") {
    auto rnd = RndNovelty::Create(scenario, config, kinds.rnd);
    if (!rnd.ok()) return rnd.status();
    return std::unique_ptr<Novelty>(*std::move(rnd));
  }
  if (kind == "sf") {
    auto sf = SfNovelty::Create(scenario, config, kinds.sf);
    if (!sf.ok()) return sf.status();
    return std::unique_ptr<Novelty>(*std::move(sf));
  }
  if (kind == "eiti" || kind == "edti") {
    if (scenario.num_actions() > 8) {
      return absl::InvalidArgumentError("eiti/edti: at most 8 actions (their count keys hold 3 bits)");
    }
    InfluenceConfig influence = kinds.influence;
    influence.edti = kind == "edti";
    if (!(influence.eta >= 0)) return absl::InvalidArgumentError("eta must be >= 0");
    if (!(influence.beta_t >= 0)) return absl::InvalidArgumentError("beta_t must be >= 0");
    return std::make_unique<InfluenceNovelty>(scenario, config, influence);
  }
  return absl::InvalidArgumentError(
      absl::StrCat("reward '", kind, "' is not one of ", absl::StrJoin(RewardKinds(), "|")));
}

absl::StatusOr<std::unique_ptr<CreditScorer>> MakeScorer(const std::string& kind, const env::Scenario& scenario,
                                                         const ScorerConfig& config, const RewardKindConfig& kinds) {
  if (!(config.beta >= 0)) return absl::InvalidArgumentError("beta must be >= 0");
  if (!(config.temperature > 0)) return absl::InvalidArgumentError("temperature must be > 0");
  auto novelty = MakeNovelty(kind, scenario, config, kinds);
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
