#ifndef IMCA_REWARD_SERVER_NOVELTY_NOVELTY_H_
#define IMCA_REWARD_SERVER_NOVELTY_NOVELTY_H_

#include <cstdint>
#include <fstream>
#include <memory>
#include <optional>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "imca/v1/reward_service.pb.h"
#include "reward_server/credit.h"
#include "reward_server/credit/registry.h"
#include "reward_server/scorer.h"

namespace imca::reward {

// What one reward kind computes for a request, before credit assignment.
// Arrays are [N] or [N][n], preallocated by the caller; a kind writes only
// those the credit rule reads (NoveltyReads; the others are null).
struct NoveltyOutput {
  // kGlobal, kContributions (shared, imca): the global novelty N(S, U).
  float* joint = nullptr;
  // kContributions (imca): each agent's contribution r^a (d^a for SF) and
  // a divisor of its reward, preset to 1 (SF writes sqrt(N_ep)).
  float* contributions = nullptr;
  double* agent_divisor = nullptr;
  // kLocal (independent): each agent's own novelty N_a.
  float* local = nullptr;
  // Kinds that ReturnsInfluences(): c_{i->j}, [N][n][n].
  float* influences = nullptr;
  // Where a kind adds the time of its parts (encode, counterfactual, train;
  // AddPart); the owner counts the rest of the call as novelty.
  ScoreSeconds* seconds = nullptr;
};

// Adds `seconds` to `phase` of out.seconds (if set).
inline void AddPart(const NoveltyOutput& out, ScorePhase phase, double seconds) {
  if (out.seconds != nullptr) SecondsOf(*out.seconds, phase) += seconds;
}

// A global novelty bonus: the part of a reward kind that is not credit
// assignment. CreditScorer calls it without knowing its kind, as Reverb's
// Table calls its ItemSelector; adding a kind means writing one of these.
// A batch's transitions are processed in order, each seeing the updates of
// the ones before it (counts) or the model as it was before the batch
// (learned kinds), as the kind's header states. Not thread-safe: as Reverb's
// selectors leave locking to their table, a novelty leaves it to its owner
// (CreditScorer), which serialises every call.
class Novelty {
 public:
  virtual ~Novelty() = default;

  // Whether this kind computes what a rule reading `reads` asks for (never
  // called with kNothing).
  virtual bool Supports(NoveltyReads reads) const = 0;
  // True if Compute writes NoveltyOutput::influences.
  virtual bool ReturnsInfluences() const { return false; }
  // Computes what the non-null arrays of `out` ask for (local, or joint
  // with or without contributions: the credit rule's reads); unless
  // dry_run, then updates counts/models. Does not fail on validated input;
  // returns INTERNAL on an internal failure (including arrays the kind was
  // not built for), with no state changed.
  virtual absl::Status Compute(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out) = 0;
  // Fills the kind-specific fields of `stats`.
  virtual void FillStats(v1::RewardStats* stats) const = 0;
  // Deterministic scoring (ScorerConfig::deterministic): the owner calls
  // this before the first call of each newer policy version. A kind makes
  // the previous version's updates visible, in (actor id, sequence) order
  // where order matters (learned kinds train then). Errors: INTERNAL.
  virtual absl::Status NewVersion() { return absl::OkStatus(); }

  // All learned state, copied out so that it can be written without holding
  // the owner's lock (Score is not blocked by I/O).
  class Snapshot {
   public:
    virtual ~Snapshot() = default;
    // Writes the state to `path` atomically (tmp file + rename). Safe
    // against the novelty's other calls; the owner serialises writes.
    virtual absl::Status Write(const std::string& path) const = 0;
  };
  // Copies the state (fast; count kinds also start the next journal).
  virtual absl::StatusOr<std::unique_ptr<Snapshot>> TakeSnapshot() = 0;
  // Replaces all learned state with the file's. Errors: NOT_FOUND, DATA_LOSS,
  // FAILED_PRECONDITION if the file was written under another configuration.
  virtual absl::Status Load(const std::string& path) = 0;
  // What a (re)starting server calls with its --snapshot path: the state as
  // it was when the last process stopped, however it stopped. Count kinds
  // load the snapshot if any, replay the journal of every increment since
  // it, and journal from now on (fdatasync'ed per Score with `sync`); so no
  // answered increment is lost (CountStore). Learned kinds load the
  // snapshot if there is one: their state is as old as it. Errors as Load's.
  virtual absl::Status Restore(const std::string& path, bool sync) {
    return std::ifstream(path).good() ? Load(path) : absl::OkStatus();
  }
  // Transitions counted into state that survives a restart (count kinds), or
  // nullopt if the kind does not keep that count.
  virtual std::optional<int64_t> DurableTransitions() const { return std::nullopt; }
};

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_NOVELTY_NOVELTY_H_
