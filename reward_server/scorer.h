#ifndef IMCA_REWARD_SERVER_SCORER_H_
#define IMCA_REWARD_SERVER_SCORER_H_

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "absl/status/status.h"
#include "imca/v1/reward_service.pb.h"

namespace imca::reward {

// A read-only view of N transitions, already validated against the scenario
// (see common/protocol/unroll_check.h). Row-major arrays.
struct TransitionBatch {
  int64_t size = 0;                     // N = length * num_envs, time-major [t][e]
  int64_t length = 0;                   // T
  int64_t num_envs = 0;                 // E
  int64_t state_size = 0;               // K, ints per state
  const int32_t* states = nullptr;      // [N][K], S_t
  const int32_t* next_states = nullptr; // [N][K], S_{t+1} (the reached state)
  const int32_t* actions = nullptr;     // [N][n]
  const float* action_probs = nullptr;  // [N][n][A], behaviour pi^a(.|o^a)
  const int64_t* episode_ids = nullptr; // [N]
  const bool* terminated = nullptr;     // [N] or null (unknown: no episode ended)
  uint64_t actor = 0;                   // Hash of the sending actor's id (episode ids are per actor).
  // The unroll's actor id, sequence, actor incarnation and acting policy
  // version: the order in which a deterministic scorer applies one
  // version's updates.
  std::string_view actor_id = {};
  int64_t sequence = 0;
  uint64_t incarnation = 0;
  int64_t policy_version = 0;
};

// Where a Score call's time goes (RewardStats.score_seconds, the metric
// imca_reward_score_seconds_total; docs/metrics.md). Count and influence
// kinds report no parts: their whole call is novelty.
enum class ScorePhase {
  kLockWait,        // Waiting for the novelty's lock (another call holds it).
  kEncode,          // Building the kind's inputs from the batch (learned kinds).
  kNovelty,         // The novelty of the taken transitions, and the rest of the kind's call.
  kCounterfactual,  // imca: the novelties of the counterfactual joint actions (learned kinds).
  kTrain,           // The learned models' optimiser step.
  kCredit,          // The credit rule over the novelties (outside the lock).
};
inline constexpr int kNumScorePhases = 6;
// "lock_wait", "encode", "novelty", "counterfactual", "train", "credit"
// (defined with the other names, in credit.cc).
std::string ScorePhaseName(ScorePhase phase);
// Seconds by ScorePhase.
using ScoreSeconds = std::array<double, kNumScorePhases>;
inline double& SecondsOf(ScoreSeconds& seconds, ScorePhase phase) { return seconds[static_cast<int>(phase)]; }

// Where a scorer writes its results; every array is preallocated by the caller.
struct ScoreOutput {
  float* global_rewards = nullptr;  // [N], R_i
  float* contributions = nullptr;   // [N][n], r^a (count, RND) or d^a (SF)
  float* shares = nullptr;          // [N][n], p^a
  float* agent_rewards = nullptr;   // [N][n], r_i^a
  float* influences = nullptr;      // [N][n][n], c_{i->j}; only if the scorer ReturnsInfluences().
  ScoreSeconds* seconds = nullptr;  // If set, the call's time by phase is added to it.
};

// A global intrinsic reward with credit assignment (CreditScorer, credit_scorer.h).
// Implementations are thread-safe: concurrent Score calls are serialised, and
// a batch's transitions are processed in order, each seeing the updates of the
// ones before it.
class Scorer {
 public:
  virtual ~Scorer() = default;

  // Scores every transition; unless dry_run, updates counts/models. Does not
  // fail on validated input; returns INTERNAL on an internal failure, with no
  // state changed.
  virtual absl::Status Score(const TransitionBatch& batch, bool dry_run, const ScoreOutput& out) = 0;
  // True if Score also writes ScoreOutput::influences (EDTI).
  virtual bool ReturnsInfluences() const { return false; }
  // Fills the kind-specific fields of `stats`.
  virtual void FillStats(v1::RewardStats* stats) const = 0;
  // Writes all learned state to `path` atomically (tmp file + rename).
  virtual absl::Status Save(const std::string& path) const = 0;
  // Replaces all learned state with the file's. Errors: NOT_FOUND, DATA_LOSS,
  // FAILED_PRECONDITION if the file was written under another configuration.
  virtual absl::Status Load(const std::string& path) = 0;
  // See Novelty::Restore and Novelty::DurableTransitions.
  virtual absl::Status Restore(const std::string& path, bool sync) = 0;
  virtual std::optional<int64_t> DurableTransitions() const = 0;
};

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_SCORER_H_
