#include "reward_server/credit_scorer.h"

#include <algorithm>
#include <vector>

#include "common/base/lap.h"
#include "common/base/status_macros.h"

namespace imca::reward {

CreditScorer::CreditScorer(std::unique_ptr<Novelty> novelty, const ScorerConfig& config, int n)
    : returns_influences_(novelty->ReturnsInfluences()),
      novelty_(std::move(novelty)),
      config_(config),
      rule_(CreditRules().Find(config.credit)),
      n_(n) {}

absl::Status CreditScorer::Compute(const TransitionBatch& batch, bool dry_run, NoveltyOutput out,
                                   ScoreSeconds* parts) {
  Clock::time_point lap = Clock::now();
  absl::MutexLock lock(&mu_);
  SecondsOf(*parts, ScorePhase::kLockWait) += Lap(lap);
  if (config_.deterministic && !dry_run &&
      (batch.policy_version != version_ || version_calls_ >= kMaxCallsPerVersion)) {
    IMCA_RETURN_IF_ERROR(novelty_->NewVersion());
    version_ = batch.policy_version;
    version_calls_ = 0;
    SecondsOf(*parts, ScorePhase::kTrain) += Lap(lap);  // The last version's updates.
  }
  if (!dry_run) ++version_calls_;
  ScoreSeconds kind{};  // The parts the kind reports.
  out.seconds = &kind;
  const absl::Status status = novelty_->Compute(batch, dry_run, out);
  double reported = 0;
  for (double part : kind) reported += part;
  // What the kind did not report of its call is novelty.
  SecondsOf(kind, ScorePhase::kNovelty) += std::max(0.0, Lap(lap) - reported);
  for (int p = 0; p < kNumScorePhases; ++p) (*parts)[p] += kind[p];
  return status;
}

void CreditScorer::FillStats(v1::RewardStats* stats) const {
  absl::MutexLock lock(&mu_);
  novelty_->FillStats(stats);
}

absl::Status CreditScorer::Save(const std::string& path) const {
  absl::MutexLock save_lock(&save_mu_);
  std::unique_ptr<Novelty::Snapshot> snapshot;
  {
    absl::MutexLock lock(&mu_);
    IMCA_ASSIGN_OR_RETURN(snapshot, novelty_->TakeSnapshot());
  }
  return snapshot->Write(path);
}

absl::Status CreditScorer::Load(const std::string& path) {
  absl::MutexLock lock(&mu_);
  version_ = kNoVersion;  // The next call starts a version on the loaded state.
  return novelty_->Load(path);
}

absl::Status CreditScorer::Restore(const std::string& path, bool sync) {
  absl::MutexLock lock(&mu_);
  version_ = kNoVersion;
  return novelty_->Restore(path, sync);
}

std::optional<int64_t> CreditScorer::DurableTransitions() const {
  absl::MutexLock lock(&mu_);
  return novelty_->DurableTransitions();
}

absl::Status CreditScorer::Score(const TransitionBatch& batch, bool dry_run, const ScoreOutput& out) {
  Clock::time_point lap = Clock::now();
  ScoreSeconds parts{};
  const absl::Status status = ApplyCredit(batch, dry_run, out, &parts);
  // The rest of the call is the credit rule's.
  double timed = 0;
  for (double part : parts) timed += part;
  SecondsOf(parts, ScorePhase::kCredit) = std::max(0.0, Lap(lap) - timed);
  if (out.seconds != nullptr) {
    for (int p = 0; p < kNumScorePhases; ++p) (*out.seconds)[p] += parts[p];
  }
  return status;
}

absl::Status CreditScorer::ApplyCredit(const TransitionBatch& batch, bool dry_run, const ScoreOutput& out,
                                       ScoreSeconds* parts) {
  if (!rule_.ok()) return rule_.status();
  const CreditRuleEntry& rule = **rule_;
  const int n = n_;
  const int64_t N = batch.size;
  CreditInput in{N, n, config_.beta, config_.temperature};
  NoveltyOutput novelty;
  novelty.influences = out.influences;
  std::vector<float> global;
  std::vector<double> divisor;
  switch (rule.reads) {
    case NoveltyReads::kNothing:
      break;
    case NoveltyReads::kLocal:  // The kind's local novelties land in contributions, reported as N_a.
      in.local = novelty.local = out.contributions;
      break;
    case NoveltyReads::kContributions:
      divisor.assign(N * n, 1.0);
      in.divisor = novelty.agent_divisor = divisor.data();
      in.contributions = novelty.contributions = out.contributions;
      [[fallthrough]];
    case NoveltyReads::kGlobal:
      global.resize(N);
      in.global = novelty.joint = global.data();
      break;
  }
  if (rule.reads != NoveltyReads::kNothing) {
    IMCA_RETURN_IF_ERROR(Compute(batch, dry_run, novelty, parts));
  } else if (out.influences != nullptr) {
    std::fill(out.influences, out.influences + N * n * n, 0.0f);
  }
  rule.apply(in, out);
  return absl::OkStatus();
}

}  // namespace imca::reward
