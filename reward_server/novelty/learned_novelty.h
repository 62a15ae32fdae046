#ifndef IMCA_REWARD_SERVER_NOVELTY_LEARNED_NOVELTY_H_
#define IMCA_REWARD_SERVER_NOVELTY_LEARNED_NOVELTY_H_

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
//   - snapshots: the kind's bytes (Serialize, from nn/archive.h) copied
//     under the owner's lock and written atomically without it.
// Torch-free; a kind keeps its models behind its own Impl. Not thread-safe
// (Novelty).
class LearnedNovelty : public Novelty {
 public:
  bool Supports(Credit) const final { return true; }
  absl::Status Compute(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out) final;
  absl::StatusOr<std::unique_ptr<Snapshot>> TakeSnapshot() final;

 protected:
  // INVALID_ARGUMENT naming `kind`'s field out of range: every hidden width
  // >= 1, learning_rate > 0, gamma in [0, 1).
  static absl::Status CheckNetwork(absl::string_view kind, const std::vector<int>& hidden, double learning_rate,
                                   double gamma);

  // `kind` names the novelty in errors ("rnd", "sf").
  LearnedNovelty(std::string kind, Credit credit);

  // The joint model's outputs (joint, and contributions for imca), or the
  // local model's (local). May throw; must change no state before it could.
  virtual void ComputeJoint(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out) = 0;
  virtual void ComputeLocal(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out) = 0;
  // After each request that succeeded (e.g. a target network's period).
  virtual void EndRequest(bool dry_run) {}
  // All learned state as a snapshot file's bytes. Errors: INTERNAL.
  virtual absl::StatusOr<std::string> Serialize() const = 0;

 private:
  const std::string kind_;
  const Credit credit_;
};

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_NOVELTY_LEARNED_NOVELTY_H_
