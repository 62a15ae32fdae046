#include "common/protocol/unroll_check.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/strip.h"
#include "common/base/checks.h"
#include "common/base/status_macros.h"

namespace imca {

std::vector<std::string> RejectionReasons() {
  std::vector<std::string> reasons(v1::Rejection_ARRAYSIZE);
  for (int r = v1::Rejection_MIN; r <= v1::Rejection_MAX; ++r) {
    if (!v1::Rejection_IsValid(r) || r == v1::REJECTION_NONE) continue;
    reasons[r] = absl::AsciiStrToLower(absl::StripPrefix(v1::Rejection_Name(r), "REJECTION_"));
  }
  return reasons;
}
namespace {

template <typename Field>
absl::Status CheckMagnitude(const Field& field, const char* name) {
  for (int i = 0; i < field.size(); ++i) {
    if (std::abs(field[i]) > kMaxAbsReward) {
      return absl::InvalidArgumentError(
          absl::StrCat("unroll.", name, "[", i, "]: ", field[i], " is outside [-1e6, 1e6]"));
    }
  }
  return absl::OkStatus();
}

// Relative tolerance between a recorded log-probability and the log of the
// recorded probability (float rounding on either side).
constexpr double kLogProbTolerance = 1e-3;

absl::Status CheckStates(const google::protobuf::RepeatedField<int32_t>& states, const char* name,
                         int64_t count, const env::Scenario& scenario) {
  const int k = scenario.state_size();
  for (int64_t i = 0; i < count; ++i) {
    absl::Status status = scenario.ValidateState(states.data() + i * k);
    if (!status.ok()) {
      return absl::InvalidArgumentError(absl::StrCat("unroll.", name, "[", i, "]: ", status.message()));
    }
  }
  return absl::OkStatus();
}

}  // namespace

absl::Status ValidateActorId(absl::string_view actor_id) {
  if (actor_id.size() > kMaxActorIdBytes) {
    return absl::InvalidArgumentError(absl::StrCat("unroll.actor_id is longer than ", kMaxActorIdBytes, " bytes"));
  }
  return absl::OkStatus();
}

absl::Status ValidateUnroll(const v1::Unroll& u, const env::Scenario& scenario,
                            const UnrollNeeds& needs) {
  if (u.scenario() != scenario.name()) {
    return absl::InvalidArgumentError(absl::StrCat("unroll.scenario '", u.scenario(),
                                                   "' is not the served scenario '", scenario.name(), "'"));
  }
  if (u.num_agents() != scenario.num_agents()) {
    return absl::InvalidArgumentError(absl::StrCat("unroll.num_agents ", u.num_agents(),
                                                   " != ", scenario.num_agents()));
  }
  if (u.num_actions() != scenario.num_actions()) {
    return absl::InvalidArgumentError(absl::StrCat("unroll.num_actions ", u.num_actions(),
                                                   " != ", scenario.num_actions()));
  }
  if (u.state_size() != scenario.state_size()) {
    return absl::InvalidArgumentError(absl::StrCat("unroll.state_size ", u.state_size(),
                                                   " != ", scenario.state_size()));
  }
  if (u.scenario_fingerprint() != 0 && u.scenario_fingerprint() != scenario.fingerprint()) {
    return absl::InvalidArgumentError(
        "unroll.scenario_fingerprint differs from this server's: the sender plays another map or other rules "
        "(check --map, --num_agents, --step_limit, --view_radius and the rewards)");
  }
  if (u.length() < 1) return absl::InvalidArgumentError("unroll.length must be >= 1");
  if (u.num_envs() < 1) return absl::InvalidArgumentError("unroll.num_envs must be >= 1");
  const int64_t transitions = int64_t{u.length()} * u.num_envs();
  if (transitions > kMaxTransitions) {
    return absl::InvalidArgumentError(absl::StrCat("unroll.length * unroll.num_envs = ", transitions,
                                                   " exceeds the limit of ", kMaxTransitions));
  }
  const int64_t n = u.num_agents(), a_count = u.num_actions(), k = u.state_size();
  IMCA_RETURN_IF_ERROR(CheckSize("unroll", "states", u.states(), (transitions + u.num_envs()) * k));
  IMCA_RETURN_IF_ERROR(CheckSize("unroll", "next_states", u.next_states(), transitions * k));
  IMCA_RETURN_IF_ERROR(CheckSize("unroll", "actions", u.actions(), transitions * n));
  IMCA_RETURN_IF_ERROR(CheckSize("unroll", "action_probs", u.action_probs(), transitions * n * a_count));
  IMCA_RETURN_IF_ERROR(CheckSize("unroll", "episode_ids", u.episode_ids(), transitions));
  for (int i = 0; i < u.actions_size(); ++i) {
    if (u.actions(i) < 0 || u.actions(i) >= a_count) {
      return absl::InvalidArgumentError(
          absl::StrCat("unroll.actions[", i, "]: ", u.actions(i), " not in [0, ", a_count, ")"));
    }
  }
  IMCA_RETURN_IF_ERROR(CheckStates(u.states(), "states", transitions + u.num_envs(), scenario));
  IMCA_RETURN_IF_ERROR(CheckStates(u.next_states(), "next_states", transitions, scenario));
  for (int64_t row = 0; row < transitions * n; ++row) {
    double sum = 0;
    for (int64_t j = 0; j < a_count; ++j) {
      const float p = u.action_probs(row * a_count + j);
      if (!std::isfinite(p) || p < 0.0f || p > 1.0f) {
        return absl::InvalidArgumentError(absl::StrCat("unroll.action_probs[", row * a_count + j,
                                                       "]: ", p, " is not a probability"));
      }
      sum += p;
    }
    if (std::abs(sum - 1.0) > 1e-3) {
      return absl::InvalidArgumentError(absl::StrCat("unroll.action_probs row ", row, " sums to ",
                                                     sum, ", not 1"));
    }
  }
  if (needs.rewards) {
    IMCA_RETURN_IF_ERROR(CheckSize("unroll", "rewards", u.rewards(), transitions * n));
    IMCA_RETURN_IF_ERROR(CheckSize("unroll", "behaviour_log_probs", u.behaviour_log_probs(), transitions * n));
    IMCA_RETURN_IF_ERROR(CheckSize("unroll", "terminated", u.terminated(), transitions));
    IMCA_RETURN_IF_ERROR(CheckSize("unroll", "truncated", u.truncated(), transitions));
    IMCA_RETURN_IF_ERROR(CheckFinite("unroll", "rewards", u.rewards()));
    IMCA_RETURN_IF_ERROR(CheckMagnitude(u.rewards(), "rewards"));
    for (int i = 0; i < u.behaviour_log_probs_size(); ++i) {
      const float lp = u.behaviour_log_probs(i);
      if (!std::isfinite(lp) || lp > 1e-4f) {
        return absl::InvalidArgumentError(
            absl::StrCat("unroll.behaviour_log_probs[", i, "]: ", lp, " is not a log-probability"));
      }
      // The log of the recorded probability of the recorded action (floored
      // at 1e-12 as the actor does): anything else would make the PPO ratio
      // meaningless.
      const float p = u.action_probs(int64_t{i} * a_count + u.actions(i));
      const double expected = std::log(std::max(static_cast<double>(p), 1e-12));
      if (std::abs(lp - expected) > kLogProbTolerance * std::max(1.0, std::abs(expected))) {
        return absl::InvalidArgumentError(absl::StrCat("unroll.behaviour_log_probs[", i, "]: ", lp,
                                                       " is not the log of action_probs[", int64_t{i} * a_count +
                                                       u.actions(i), "] = ", p, " (", expected, ")"));
      }
    }
  }
  if (u.terminated_size() != 0) IMCA_RETURN_IF_ERROR(CheckSize("unroll", "terminated", u.terminated(), transitions));
  IMCA_RETURN_IF_ERROR(CheckFinite("unroll", "episode_returns", u.episode_returns()));
  IMCA_RETURN_IF_ERROR(CheckFinite("unroll", "eval_returns", u.eval_returns()));
  IMCA_RETURN_IF_ERROR(ValidateActorId(u.actor_id()));
  if (needs.intrinsic_rewards) {
    IMCA_RETURN_IF_ERROR(CheckSize("unroll", "intrinsic_rewards", u.intrinsic_rewards(), transitions * n));
    IMCA_RETURN_IF_ERROR(CheckFinite("unroll", "intrinsic_rewards", u.intrinsic_rewards()));
    IMCA_RETURN_IF_ERROR(CheckMagnitude(u.intrinsic_rewards(), "intrinsic_rewards"));
    if (u.credit_shares_size() != 0) {
      IMCA_RETURN_IF_ERROR(CheckSize("unroll", "credit_shares", u.credit_shares(), transitions * n));
    }
    if (u.global_rewards_size() != 0) {
      IMCA_RETURN_IF_ERROR(CheckSize("unroll", "global_rewards", u.global_rewards(), transitions));
      IMCA_RETURN_IF_ERROR(CheckFinite("unroll", "global_rewards", u.global_rewards()));
    }
    if (u.contributions_size() != 0) {
      IMCA_RETURN_IF_ERROR(CheckSize("unroll", "contributions", u.contributions(), transitions * n));
      IMCA_RETURN_IF_ERROR(CheckFinite("unroll", "contributions", u.contributions()));
    }
  }
  if (needs.influences) {
    if (u.influences_size() == 0) {
      return absl::InvalidArgumentError(
          "unroll.influences is empty: an EDTI learner needs the reward server's influences (--reward edti)");
    }
    IMCA_RETURN_IF_ERROR(CheckSize("unroll", "influences", u.influences(), transitions * n * n));
    IMCA_RETURN_IF_ERROR(CheckFinite("unroll", "influences", u.influences()));
  } else if (u.influences_size() != 0) {
    IMCA_RETURN_IF_ERROR(CheckSize("unroll", "influences", u.influences(), transitions * n * n));
  }
  return absl::OkStatus();
}

}  // namespace imca
