#ifndef IMCA_REWARD_SERVER_CREDIT_SCORER_H_
#define IMCA_REWARD_SERVER_CREDIT_SCORER_H_

#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <string>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/synchronization/mutex.h"
#include "reward_server/credit.h"
#include "reward_server/credit/registry.h"
#include "reward_server/novelty/novelty.h"
#include "reward_server/scorer.h"

namespace imca::reward {

// Deterministic scoring: the calls one policy version may hold before the
// scorer starts another (CreditScorer); a synchronous run makes a handful.
inline constexpr int64_t kMaxCallsPerVersion = 1024;

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
// Thread-safe: one mutex serialises the novelty's calls (the credit rule runs
// outside it); a snapshot is copied under it and written without it.
// Deterministic (config.deterministic): a call (not a dry run) of another
// policy version than the last call's first has the novelty close the last
// one (Novelty::NewVersion): in a synchronous run versions only grow, and a
// learner restarted from an older checkpoint, or several clients of their
// own, then start versions as they change. So does a call after
// kMaxCallsPerVersion calls of one version, which bounds what a version
// keeps (a client that never changes its version).
// ScoreOutput::seconds gets the call's lock wait, the kind's parts and the
// credit rule's time.
class CreditScorer : public Scorer {
 public:
  // `n` agents, credit rule config.credit (credit/registry.h). The caller
  // checks the rule exists and novelty->Supports(its reads) first
  // (MakeScorer does); Score refuses an unknown rule.
  CreditScorer(std::unique_ptr<Novelty> novelty, const ScorerConfig& config, int n);

  absl::Status Score(const TransitionBatch& batch, bool dry_run, const ScoreOutput& out) override;
  bool ReturnsInfluences() const override { return returns_influences_; }
  void FillStats(v1::RewardStats* stats) const override;
  absl::Status Save(const std::string& path) const override;
  absl::Status Load(const std::string& path) override;
  absl::Status Restore(const std::string& path, bool sync) override;
  std::optional<int64_t> DurableTransitions() const override;

  // Tests: the novelty itself, for probes, while no other call is in flight.
  Novelty& novelty() ABSL_NO_THREAD_SAFETY_ANALYSIS { return *novelty_; }

 private:
  // Score without the credit rule's time: the credit rule over Compute.
  absl::Status ApplyCredit(const TransitionBatch& batch, bool dry_run, const ScoreOutput& out,
                           ScoreSeconds* parts);
  // The novelty's call under the lock; adds the lock wait, the kind's parts
  // and the rest of its call (novelty) to *parts.
  absl::Status Compute(const TransitionBatch& batch, bool dry_run, NoveltyOutput out, ScoreSeconds* parts)
      ABSL_LOCKS_EXCLUDED(mu_);

  mutable absl::Mutex save_mu_ ABSL_ACQUIRED_BEFORE(mu_);  // Serialises snapshot writes.
  mutable absl::Mutex mu_;
  const bool returns_influences_;
  const std::unique_ptr<Novelty> novelty_ ABSL_PT_GUARDED_BY(mu_);
  // Deterministic: the policy version scored last (Novelty::NewVersion), and
  // the calls (not dry runs) of it so far.
  static constexpr int64_t kNoVersion = std::numeric_limits<int64_t>::min();
  int64_t version_ ABSL_GUARDED_BY(mu_) = kNoVersion;
  int64_t version_calls_ ABSL_GUARDED_BY(mu_) = 0;
  const ScorerConfig config_;
  const absl::StatusOr<const CreditRuleEntry*> rule_;
  const int n_;
};

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_CREDIT_SCORER_H_
