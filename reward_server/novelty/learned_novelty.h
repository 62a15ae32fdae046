#ifndef IMCA_REWARD_SERVER_NOVELTY_LEARNED_NOVELTY_H_
#define IMCA_REWARD_SERVER_NOVELTY_LEARNED_NOVELTY_H_

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "reward_server/credit.h"
#include "reward_server/novelty/novelty.h"

namespace imca::reward {

// The scaffold of the learned novelties (RND, SF): a kind holds a joint model
// (shared and imca credit) or a local one over each agent's own input
// (independent credit), never both. This class owns what they share:
//   - the checks of the sizes every network has (CheckNetwork);
//   - Compute: the arrays asked for must match the model the credit mode
//     built, LibTorch's exceptions come back as INTERNAL naming the kind,
//     and EndRequest runs after each request;
//   - snapshots: the kind's bytes (Serialize, from common/nn/archive.h) copied
//     under the owner's lock and written atomically without it.
// Torch-free; a kind keeps its models behind its own Impl. Not thread-safe
// (Novelty).
class LearnedNovelty : public Novelty {
 public:
  bool Supports(NoveltyReads) const final { return true; }
  absl::Status Compute(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out) final;
  absl::StatusOr<std::unique_ptr<Snapshot>> TakeSnapshot() final;
  // Deterministic: runs the updates the last version's calls deferred, in
  // (actor id, sequence, incarnation) order. Errors: INTERNAL if one throws;
  // the updates after it stay pending (the next call runs them).
  absl::Status NewVersion() final;

 protected:
  // INVALID_ARGUMENT naming `kind`'s field out of range: every hidden width
  // >= 1, learning_rate > 0, gamma in [0, 1).
  static absl::Status CheckNetwork(absl::string_view kind, const std::vector<int>& hidden, double learning_rate,
                                   double gamma);

  // `kind` names the novelty in errors ("rnd", "sf"); `reads`, what credit
  // rule `credit` reads, says which model it has. `deterministic`: a call's
  // updates are deferred to the next version (Deferred).
  LearnedNovelty(std::string kind, std::string credit, NoveltyReads reads, bool deterministic);

  // Deterministic scoring outside a dry run: the call scores with the models
  // as they are (the version's start) and leaves them unchanged, appending
  // each update it would have made (which may throw) to the Deferred it is
  // given instead; NewVersion runs them, call by call in (actor id,
  // sequence, incarnation) order, each call's then its EndRequest.
  // (Per-episode state keyed by the actor's incarnation, as SF's visit
  // counts, is not shared between calls and is kept at once.)
  using Deferred = std::vector<std::function<void()>>;
  // Drops what the current version deferred (a kind's Load replaces the
  // models they were for).
  void DropPending() { pending_.clear(); }

  // The joint model's outputs (joint, and contributions for imca), or the
  // local model's (local). May throw; must change no state before it could.
  // `deferred`: null, or where a deterministic call's updates go (Deferred).
  virtual void ComputeJoint(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out,
                            Deferred* deferred) = 0;
  virtual void ComputeLocal(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out,
                            Deferred* deferred) = 0;
  // After each request that succeeded (e.g. a target network's period).
  virtual void EndRequest(bool dry_run) {}
  // All learned state as a snapshot file's bytes. Errors: INTERNAL.
  virtual absl::StatusOr<std::string> Serialize() const = 0;

 private:
  // One call's deferred updates.
  struct Pending {
    std::string actor_id;
    int64_t sequence = 0;
    uint64_t incarnation = 0;
    Deferred updates;
  };

  const std::string kind_;
  const std::string credit_;
  const NoveltyReads reads_;
  const bool deterministic_;
  std::vector<Pending> pending_;  // The current version's calls'.
};

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_NOVELTY_LEARNED_NOVELTY_H_
