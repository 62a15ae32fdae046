#include "reward_server/count_scorer.h"

#include <cmath>
#include <cstdio>
#include <fstream>

#include "absl/strings/str_cat.h"
#include "common/status_macros.h"

namespace imca::reward {
namespace {

constexpr char kMagic[] = "IMCA-COUNT-1";

float Novelty(uint32_t count_before) {
  return static_cast<float>(1.0 / std::sqrt(static_cast<double>(count_before) + 1.0));
}

}  // namespace

CountScorer::CountScorer(const env::Scenario& scenario, const ScorerConfig& config)
    : scenario_tag_(absl::StrCat(scenario.name(), " ", scenario.map().width(), "x", scenario.map().height())),
      n_(scenario.num_agents()),
      num_actions_(scenario.num_actions()),
      k_(scenario.state_size()),
      config_(config),
      codec_(scenario),
      rng_(config.seed) {}

uint32_t CountScorer::JointCount(const int32_t* state, const int32_t* actions) const {
  int order[env::kMaxAgents];
  codec_.SlotOrder(state, config_.permutation == Permutation::kCanonical, order);
  absl::MutexLock lock(&mu_);
  return global_.Get(codec_.GlobalKey(state, actions, order));
}

absl::Status CountScorer::Score(const TransitionBatch& batch, bool dry_run, const ScoreOutput& out) {
  absl::MutexLock lock(&mu_);
  for (int64_t i = 0; i < batch.size; ++i) {
    ScoreOne(batch.states + i * k_, batch.actions + i * n_, batch.action_probs + i * n_ * num_actions_,
             dry_run, out.global_rewards + i, out.contributions + i * n_, out.shares + i * n_,
             out.agent_rewards + i * n_);
  }
  return absl::OkStatus();
}

void CountScorer::ScoreOne(const int32_t* state, const int32_t* actions, const float* probs,
                           bool dry_run, float* global, float* contributions, float* shares,
                           float* agent_rewards) {
  const float beta = static_cast<float>(config_.beta);
  *global = 0;
  for (int a = 0; a < n_; ++a) contributions[a] = agent_rewards[a] = 0;

  if (config_.credit == Credit::kIndependent) {
    const bool shared_table = config_.permutation != Permutation::kOff;
    for (int a = 0; a < n_; ++a) {
      const uint64_t key = codec_.LocalKey(state, a, actions[a], shared_table);
      contributions[a] = Novelty(local_.Get(key));
      agent_rewards[a] = beta * contributions[a];
      *global += agent_rewards[a];
    }
    if (!dry_run) {
      for (int a = 0; a < n_; ++a) local_.Increment(codec_.LocalKey(state, a, actions[a], shared_table));
    }
  } else if (config_.credit != Credit::kNone) {
    int order[env::kMaxAgents];
    codec_.SlotOrder(state, config_.permutation == Permutation::kCanonical, order);
    const uint64_t key = codec_.GlobalKey(state, actions, order);
    const float novelty = Novelty(global_.Get(key));
    *global = beta * novelty;
    if (config_.credit == Credit::kShared) {
      for (int a = 0; a < n_; ++a) agent_rewards[a] = *global;
    } else {
      // Counterfactuals: agent a's action replaced by every u', all probed
      // against the counts before this transition's increment.
      int32_t counterfactual[env::kMaxAgents];
      for (int a = 0; a < n_; ++a) counterfactual[a] = actions[a];
      for (int a = 0; a < n_; ++a) {
        double baseline = 0;
        for (int u = 0; u < num_actions_; ++u) {
          counterfactual[a] = u;
          // The taken action's pair is (S, U) itself: its novelty was read above.
          const float n_u = u == actions[a] ? novelty
                                            : Novelty(global_.Get(codec_.GlobalKey(state, counterfactual, order)));
          baseline += probs[a * num_actions_ + u] * n_u;
        }
        counterfactual[a] = actions[a];
        contributions[a] = static_cast<float>(novelty - baseline);
      }
      SoftmaxShares(contributions, n_, config_.temperature, shares);
      for (int a = 0; a < n_; ++a) agent_rewards[a] = shares[a] * *global;
    }
    if (!dry_run) {
      if (config_.permutation == Permutation::kRandom) {
        for (int slot = n_ - 1; slot > 0; --slot) std::swap(order[slot], order[rng_.Uniform(slot + 1)]);
        global_.Increment(codec_.GlobalKey(state, actions, order));
      } else {
        global_.Increment(key);
      }
    }
  }

  if (config_.credit == Credit::kImca) return;
  float total = 0;
  for (int a = 0; a < n_; ++a) total += agent_rewards[a];
  for (int a = 0; a < n_; ++a) shares[a] = total > 0 ? agent_rewards[a] / total : 1.0f / n_;
}

void CountScorer::FillStats(v1::RewardStats* stats) const {
  absl::MutexLock lock(&mu_);
  stats->set_distinct_keys(global_.size());
  stats->set_distinct_local_keys(local_.size());
}

std::string CountScorer::ConfigTag() const {
  return absl::StrCat(kMagic, " ", scenario_tag_, " n=", n_, " A=", num_actions_,
                      " exact=", codec_.exact(), " credit=", CreditName(config_.credit),
                      " permutation=", PermutationName(config_.permutation), "\n");
}

absl::Status CountScorer::Save(const std::string& path) const {
  absl::MutexLock save_lock(&save_mu_);
  // Copy under the lock (fast), write without it, so Score is not blocked by I/O.
  CountTable global, local;
  {
    absl::MutexLock lock(&mu_);
    global = global_;
    local = local_;
  }
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) return absl::InternalError(absl::StrCat("cannot write snapshot '", tmp, "'"));
    const std::string tag = ConfigTag();
    out.write(tag.data(), tag.size());
    IMCA_RETURN_IF_ERROR(global.Write(out));
    IMCA_RETURN_IF_ERROR(local.Write(out));
    out.flush();
    if (!out) return absl::InternalError(absl::StrCat("writing snapshot '", tmp, "' failed"));
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    return absl::InternalError(absl::StrCat("cannot rename snapshot to '", path, "'"));
  }
  return absl::OkStatus();
}

absl::Status CountScorer::Load(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::NotFoundError(absl::StrCat("no snapshot at '", path, "'"));
  std::string tag;
  std::getline(in, tag);
  if (tag + "\n" != ConfigTag()) {
    return absl::FailedPreconditionError(absl::StrCat("snapshot '", path, "' was written by '", tag,
                                                      "', not by this configuration"));
  }
  CountTable global, local;
  IMCA_RETURN_IF_ERROR(global.Read(in));
  IMCA_RETURN_IF_ERROR(local.Read(in));
  absl::MutexLock lock(&mu_);
  global_ = std::move(global);
  local_ = std::move(local);
  return absl::OkStatus();
}

}  // namespace imca::reward
