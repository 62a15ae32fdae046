#ifndef IMCA_REWARD_SERVER_NOVELTY_H_
#define IMCA_REWARD_SERVER_NOVELTY_H_

#include <cstdint>
#include <fstream>
#include <memory>
#include <optional>
#include <string>

#include "absl/status/status.h"
#include "imca/v1/reward_service.pb.h"
#include "reward_server/credit.h"
#include "reward_server/scorer.h"

namespace imca::reward {

// What one reward kind computes for a request, before credit assignment.
// Arrays are [N] or [N][n], preallocated by the caller; a kind writes only
// those its credit mode needs (the others are null).
struct NoveltyOutput {
  // Joint credit (shared, imca): the global novelty N(S, U), so R_i = beta * joint.
  float* joint = nullptr;
  // imca only: each agent's contribution r^a (d^a for SF) and a divisor of
  // its reward, preset to 1 (SF writes sqrt(N_ep)).
  float* contributions = nullptr;
  double* agent_divisor = nullptr;
  // Independent credit: each agent's own novelty, r_i^a = beta * local.
  float* local = nullptr;
  // Kinds that ReturnsInfluences(): c_{i->j}, [N][n][n].
  float* influences = nullptr;
};

// A global novelty bonus: the part of a reward kind that is not credit
// assignment. CreditScorer calls it without knowing its kind, as Reverb's
// Table calls its ItemSelector; adding a kind means writing one of these.
// Implementations are thread-safe: concurrent Compute calls are serialised,
// and a batch's transitions are processed in order, each seeing the updates of
// the ones before it (counts) or the model as it was before the batch
// (learned kinds), as the kind's header states.
class Novelty {
 public:
  virtual ~Novelty() = default;

  // Whether this kind can serve `credit` (never called with kNone).
  virtual bool Supports(Credit credit) const = 0;
  // True if Compute writes NoveltyOutput::influences.
  virtual bool ReturnsInfluences() const { return false; }
  // Computes what the non-null arrays of `out` ask for (local for
  // independent credit, else joint, with contributions for imca); unless
  // dry_run, then updates counts/models. Does not fail on validated input;
  // returns INTERNAL on an internal failure (including arrays the kind was
  // not built for), with no state changed.
  virtual absl::Status Compute(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out) = 0;
  // Fills the kind-specific fields of `stats`.
  virtual void FillStats(v1::RewardStats* stats) const = 0;
  // Writes all learned state to `path` atomically (tmp file + rename).
  virtual absl::Status Save(const std::string& path) const = 0;
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

// The one credit rule (docs/credit.md) over any Novelty:
//   none:        every output 0, shares 1/n; the novelty is not called.
//   shared:      r_i^a = R_i = beta * N(S, U).
//   independent: r_i^a = beta * N_a (the kind's local novelty); R_i is
//                reported as the team sum.
//   imca:        p^a = softmax(r^a / tau), r_i^a = p^a * R_i / divisor^a.
// contributions report r^a (imca) or N_a (independent), 0 otherwise; shares
// report p^a for imca, 1/n for shared, and r_i^a / sum_b r_i^b for
// independent (1/n when the sum is not positive; with EITI's negative
// influences a share can fall outside [0, 1]: they are diagnostics only).
// Thread-safe if the novelty is.
class CreditScorer : public Scorer {
 public:
  // `n` agents. The caller checks novelty->Supports(config.credit) first
  // (MakeScorer does).
  CreditScorer(std::unique_ptr<Novelty> novelty, const ScorerConfig& config, int n);

  absl::Status Score(const TransitionBatch& batch, bool dry_run, const ScoreOutput& out) override;
  bool ReturnsInfluences() const override { return novelty_->ReturnsInfluences(); }
  void FillStats(v1::RewardStats* stats) const override { novelty_->FillStats(stats); }
  absl::Status Save(const std::string& path) const override { return novelty_->Save(path); }
  absl::Status Load(const std::string& path) override { return novelty_->Load(path); }
  absl::Status Restore(const std::string& path, bool sync) override { return novelty_->Restore(path, sync); }
  std::optional<int64_t> DurableTransitions() const override { return novelty_->DurableTransitions(); }

  Novelty& novelty() { return *novelty_; }

 private:
  const std::unique_ptr<Novelty> novelty_;
  const ScorerConfig config_;
  const int n_;
};

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_NOVELTY_H_
