#include "reward_server/novelty.h"

#include <algorithm>
#include <vector>

namespace imca::reward {

CreditScorer::CreditScorer(std::unique_ptr<Novelty> novelty, const ScorerConfig& config, int n)
    : novelty_(std::move(novelty)), config_(config), n_(n) {}

absl::Status CreditScorer::Score(const TransitionBatch& batch, bool dry_run, const ScoreOutput& out) {
  const int n = n_;
  const int64_t N = batch.size;
  if (config_.credit == Credit::kNone) {
    WriteNoCredit(batch, n, out);
    if (out.influences != nullptr) std::fill(out.influences, out.influences + N * n * n, 0.0f);
    return absl::OkStatus();
  }
  const bool imca = config_.credit == Credit::kImca;
  const bool independent = config_.credit == Credit::kIndependent;
  std::vector<float> joint(independent ? 0 : N), local(independent ? N * n : 0);
  std::vector<double> divisor(imca ? N * n : 0, 1.0);
  NoveltyOutput novelty;
  if (independent) {
    novelty.local = local.data();
  } else {
    novelty.joint = joint.data();
  }
  if (imca) {
    novelty.contributions = out.contributions;
    novelty.agent_divisor = divisor.data();
  }
  novelty.influences = out.influences;
  if (absl::Status status = novelty_->Compute(batch, config_.credit, dry_run, novelty); !status.ok()) return status;

  const float beta = static_cast<float>(config_.beta);
  for (int64_t i = 0; i < N; ++i) {
    float* contributions = out.contributions + i * n;
    float* shares = out.shares + i * n;
    float* rewards = out.agent_rewards + i * n;
    if (imca) {
      out.global_rewards[i] = beta * joint[i];
      SoftmaxShares(contributions, n, config_.temperature, shares);
      for (int a = 0; a < n; ++a) {
        rewards[a] = static_cast<float>(shares[a] * out.global_rewards[i] / divisor[i * n + a]);
      }
      continue;
    }
    float total = 0;
    for (int a = 0; a < n; ++a) {
      if (independent) {
        contributions[a] = local[i * n + a];
        rewards[a] = beta * local[i * n + a];
      } else {
        contributions[a] = 0;
        rewards[a] = beta * joint[i];
      }
      total += rewards[a];
    }
    out.global_rewards[i] = independent ? total : beta * joint[i];
    for (int a = 0; a < n; ++a) shares[a] = independent && total > 0 ? rewards[a] / total : 1.0f / n;
  }
  return absl::OkStatus();
}

}  // namespace imca::reward
