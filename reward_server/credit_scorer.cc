#include "reward_server/credit_scorer.h"

#include <algorithm>
#include <vector>

#include "base/lap.h"
#include "base/status_macros.h"

namespace imca::reward {

CreditScorer::CreditScorer(std::unique_ptr<Novelty> novelty, const ScorerConfig& config, int n)
    : returns_influences_(novelty->ReturnsInfluences()), novelty_(std::move(novelty)), config_(config), n_(n) {}

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
  const int n = n_;
  const int64_t N = batch.size;
  const float beta = static_cast<float>(config_.beta);
  if (config_.credit == Credit::kNone) {
    std::fill(out.global_rewards, out.global_rewards + N, 0.0f);
    std::fill(out.contributions, out.contributions + N * n, 0.0f);
    std::fill(out.agent_rewards, out.agent_rewards + N * n, 0.0f);
    std::fill(out.shares, out.shares + N * n, 1.0f / n);
    if (out.influences != nullptr) std::fill(out.influences, out.influences + N * n * n, 0.0f);
    return absl::OkStatus();
  }
  NoveltyOutput novelty;
  novelty.influences = out.influences;

  if (config_.credit == Credit::kIndependent) {
    // The kind's local novelties land in contributions, reported as N_a.
    novelty.local = out.contributions;
    IMCA_RETURN_IF_ERROR(Compute(batch, dry_run, novelty, parts));
    for (int64_t i = 0; i < N; ++i) {
      const float* local = out.contributions + i * n;
      float* rewards = out.agent_rewards + i * n;
      float total = 0;
      for (int a = 0; a < n; ++a) total += rewards[a] = beta * local[a];
      out.global_rewards[i] = total;
      for (int a = 0; a < n; ++a) out.shares[i * n + a] = total > 0 ? rewards[a] / total : 1.0f / n;
    }
    return absl::OkStatus();
  }

  std::vector<float> joint(N);
  novelty.joint = joint.data();
  if (config_.credit == Credit::kShared) {
    IMCA_RETURN_IF_ERROR(Compute(batch, dry_run, novelty, parts));
    for (int64_t i = 0; i < N; ++i) {
      out.global_rewards[i] = beta * joint[i];
      for (int a = 0; a < n; ++a) {
        out.contributions[i * n + a] = 0;
        out.agent_rewards[i * n + a] = out.global_rewards[i];
        out.shares[i * n + a] = 1.0f / n;
      }
    }
    return absl::OkStatus();
  }

  // imca.
  std::vector<double> divisor(N * n, 1.0);
  novelty.contributions = out.contributions;
  novelty.agent_divisor = divisor.data();
  IMCA_RETURN_IF_ERROR(Compute(batch, dry_run, novelty, parts));
  for (int64_t i = 0; i < N; ++i) {
    out.global_rewards[i] = beta * joint[i];
    float* shares = out.shares + i * n;
    SoftmaxShares(out.contributions + i * n, n, config_.temperature, shares);
    for (int a = 0; a < n; ++a) {
      out.agent_rewards[i * n + a] = static_cast<float>(shares[a] * out.global_rewards[i] / divisor[i * n + a]);
    }
  }
  return absl::OkStatus();
}

}  // namespace imca::reward
