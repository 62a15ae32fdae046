#ifndef IMCA_REWARD_SERVER_MAKE_SCORER_H_
#define IMCA_REWARD_SERVER_MAKE_SCORER_H_

#include <memory>
#include <string>
#include <vector>

#include <any>

#include "absl/status/statusor.h"
#include "common/env/env.h"
#include "reward_server/credit.h"
#include "reward_server/credit_scorer.h"
#include "reward_server/novelty/novelty.h"

namespace imca::reward {

// The registered reward kinds (novelty/registry.h), the default first.
std::vector<std::string> RewardKinds();

// The scorer defaults of reward kind `kind` on scenario `scenario`:
// ScorerConfig's, joined with the kind's own (its registry entry: count, rnd,
// sf credit imca and beta 0.5; eiti, edti credit independent and beta 1,
// their own coefficients setting the scale), beta times the scenario's
// bonus_scale (env::TuningOf). An unknown kind gets ScorerConfig's, beta
// scaled the same (MakeScorer then names the known kinds); an unknown
// scenario no scale. The reward server's flags override them; --list prints
// them per kind and scenario.
ScorerConfig DefaultScorerConfig(const std::string& kind, absl::string_view scenario);

// The Novelty of reward kind `kind` for `scenario`, with the kind's own
// settings `options` (its entry's options type; none: its defaults).
// Errors: INVALID_ARGUMENT for an unknown kind (naming the known ones) or bad
// kind settings.
absl::StatusOr<std::unique_ptr<Novelty>> MakeNovelty(const std::string& kind, const env::Scenario& scenario,
                                                     const ScorerConfig& config, const std::any& options = {});

// The credit rules (credit/rules.def) `novelty` serves: those reading
// nothing and those whose reads it Supports.
std::vector<std::string> ServedCredits(const Novelty& novelty);

// That novelty under the credit rule of config.credit. Errors: those of
// MakeNovelty, and INVALID_ARGUMENT for an unknown credit rule (naming
// --credit and the rules), one the kind cannot serve, or beta < 0 or
// temperature <= 0 (naming the field).
absl::StatusOr<std::unique_ptr<CreditScorer>> MakeScorer(const std::string& kind, const env::Scenario& scenario,
                                                         const ScorerConfig& config, const std::any& options = {});

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_MAKE_SCORER_H_
