#ifndef IMCA_COMMON_PROTOCOL_UNROLL_CHECK_H_
#define IMCA_COMMON_PROTOCOL_UNROLL_CHECK_H_

#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "common/env/env.h"
#include "imca/v1/learner_service.pb.h"
#include "imca/v1/unroll.pb.h"

namespace imca {

// What a receiver of an Unroll needs from it.
struct UnrollNeeds {
  bool rewards = false;            // rewards, terminated, truncated, log-probs.
  bool intrinsic_rewards = false;  // intrinsic_rewards (learner side).
  bool influences = false;         // influences [T][E][n][n] (an EDTI learner).
};

// Largest number of transitions (T*E) one message may carry.
inline constexpr int kMaxTransitions = 65536;
// Largest |reward| (extrinsic or intrinsic) an unroll may carry: well above
// any scenario's (pass pays 1000) and any bonus, far below what would make
// returns overflow a float.
inline constexpr float kMaxAbsReward = 1e6f;

// The reason of each v1::Rejection, indexed by it: its lower-case name
// without the prefix ("over_cap" for REJECTION_OVER_CAP), "" for
// REJECTION_NONE. The reason label of the refused-unroll metrics
// (metrics::Registry::AddCounterPerValue).
std::vector<std::string> RejectionReasons();

// Longest unroll.actor_id accepted, bytes.
inline constexpr size_t kMaxActorIdBytes = 256;
// INVALID_ARGUMENT "unroll.actor_id is longer than 256 bytes" past it. What
// ValidateUnroll checks first; servers that key state by the id before the
// rest is validated call it alone. Pure.
absl::Status ValidateActorId(absl::string_view actor_id);

// Checks an Unroll against the scenario it claims to come from: scenario name,
// fingerprint (unless 0), agent/action counts and state size; T, E >= 1 and T*E <= kMaxTransitions;
// every packed field's length; actions in [0, A); every state a valid state of
// the scenario; action_probs finite, in [0,1] and each row summing to 1 within
// 1e-3; with `rewards`, each behaviour log-probability the log of the
// recorded probability of the recorded action (floored at 1e-12, within a
// relative 1e-3); rewards within kMaxAbsReward. Returns INVALID_ARGUMENT whose message names the field and element
// (e.g. "unroll.actions[12]: 7 not in [0, 5)"). Pure; thread-safe.
// Joint env steps (transitions per agent) an unroll holds: length x envs.
inline int64_t UnrollSteps(const v1::Unroll& u) { return int64_t{u.length()} * u.num_envs(); }

absl::Status ValidateUnroll(const v1::Unroll& unroll, const env::Scenario& scenario,
                            const UnrollNeeds& needs);

}  // namespace imca

#endif  // IMCA_COMMON_PROTOCOL_UNROLL_CHECK_H_
