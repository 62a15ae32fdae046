#include "reward_server/reward_service.h"

#include <sys/stat.h>

#include <chrono>
#include <cstdio>
#include <functional>

#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "common/nn/blas_kernels.h"
#include "common/protocol/unroll_check.h"
#include "common/rpc/grpc_util.h"
#include "common/rpc/transport.h"

namespace imca::reward {

RewardServiceImpl::RewardServiceImpl(const env::Scenario* scenario, Scorer* scorer,
                                     std::string reward_kind, ScorerConfig config,
                                     std::string snapshot_path, ServiceLimits limits)
    : scenario_(scenario),
      scorer_(scorer),
      reward_kind_(std::move(reward_kind)),
      config_(config),
      snapshot_path_(std::move(snapshot_path)),
      inflight_(limits.max_inflight, limits.max_inflight_per_actor),
      max_tracked_actors_(limits.max_tracked_actors) {
  struct Exported {
    metrics::Family family;
    int64_t (v1::RewardStats::*value)() const;
  };
  static const Exported kExported[] = {
      {{"imca_reward_transitions_scored_total", metrics::Type::kCounter,
        "Transitions scored (count kinds: since the tables began, restarts included)."},
       &v1::RewardStats::transitions_scored},
      {{"imca_reward_requests_total", metrics::Type::kCounter, "Score requests answered."},
       &v1::RewardStats::requests_served},
      {{"imca_reward_requests_rejected_total", metrics::Type::kCounter,
        "Score requests refused or failed (invalid, over a bound, while stopping, or a scorer error)."},
       &v1::RewardStats::requests_rejected},
      {{"imca_reward_requests_repeated_total", metrics::Type::kCounter,
        "Score requests repeating an already scored sequence (answered, not counted again)."},
       &v1::RewardStats::requests_repeated},
      {{"imca_reward_table_entries", metrics::Type::kGauge, "Keys in the global count table (count kinds)."},
       &v1::RewardStats::distinct_keys},
      {{"imca_reward_local_table_entries", metrics::Type::kGauge,
        "Keys in the per-agent count tables (count kinds)."},
       &v1::RewardStats::distinct_local_keys},
      {{"imca_reward_model_updates_total", metrics::Type::kCounter,
        "Optimiser steps of the learned novelty models (rnd, sf)."},
       &v1::RewardStats::model_updates},
  };
  // Before the snapshot: its first read (now) takes Stats(), which reads them.
  for (int p = 0; p < kNumScorePhases; ++p) {
    score_seconds_[p] = &registry_.AddCounter(
        {"imca_reward_score_seconds_total", metrics::Type::kCounter,
         "Answered Score calls' seconds by phase: lock_wait, encode, novelty, counterfactual, train, credit."},
        {{"phase", ScorePhaseName(static_cast<ScorePhase>(p))}});
  }
  handler_seconds_ = &registry_.AddCounter({"imca_reward_score_handler_seconds_total", metrics::Type::kCounter,
                                            "Answered Score calls' seconds in the handler, validation to answer."});
  // One Stats() per scrape (it takes the scorer's lock) for every family.
  registry_.AddSnapshot([this](metrics::Snapshot& snapshot) {
    const v1::RewardStats stats = Stats();
    for (const Exported& e : kExported) snapshot.Set(e.family, static_cast<double>((stats.*e.value)()));
  });
}

grpc::Status RewardServiceImpl::Score(grpc::ServerContext* context, const v1::ScoreRequest* request,
                                      v1::ScoreResponse* response) {
  const auto entered = std::chrono::steady_clock::now();
  if (!accepting_.load()) {
    ++requests_rejected_;
    return grpc::Status(grpc::StatusCode::UNAVAILABLE, "reward server is shutting down");
  }
  // The id keys the admission bound, so its size is checked first (the
  // rest of the unroll after admission).
  if (absl::Status id = ValidateActorId(request->unroll().actor_id()); !id.ok()) {
    ++requests_rejected_;
    return ToGrpcStatus(id);
  }
  absl::StatusOr<ConcurrencyLimiter::Slot> slot = inflight_.Acquire(request->unroll().actor_id());
  if (!slot.ok()) {
    ++requests_rejected_;
    return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                        absl::StrCat("reward server busy: ", slot.status().message(),
                                     " (--max_inflight, --max_inflight_per_actor); retry later"));
  }
  if (!request->has_unroll()) {
    ++requests_rejected_;
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "unroll is missing");
  }
  const v1::Unroll& unroll = request->unroll();
  if (absl::Status valid = ValidateUnroll(unroll, *scenario_, {}); !valid.ok()) {
    ++requests_rejected_;
    return ToGrpcStatus(valid);
  }
  const int64_t count = int64_t{unroll.length()} * unroll.num_envs();
  const int n = unroll.num_agents();
  response->set_num_transitions(static_cast<int32_t>(count));
  response->set_num_agents(n);
  response->mutable_global_rewards()->Resize(count, 0.0f);
  response->mutable_contributions()->Resize(count * n, 0.0f);
  response->mutable_shares()->Resize(count * n, 0.0f);
  response->mutable_agent_rewards()->Resize(count * n, 0.0f);
  TransitionBatch batch;
  batch.size = count;
  batch.length = unroll.length();
  batch.num_envs = unroll.num_envs();
  batch.state_size = unroll.state_size();
  batch.states = unroll.states().data();
  batch.next_states = unroll.next_states().data();
  batch.actions = unroll.actions().data();
  batch.action_probs = unroll.action_probs().data();
  batch.episode_ids = unroll.episode_ids().data();
  if (unroll.terminated_size() == count) batch.terminated = unroll.terminated().data();
  // Per-episode state is keyed by the producing process: a restarted actor
  // (a new incarnation) numbers its episodes afresh and must not continue
  // the dead one's.
  batch.actor = std::hash<std::string>()(unroll.actor_id()) ^ (unroll.incarnation() * 0x9e3779b97f4a7c15ULL);
  batch.actor_id = unroll.actor_id();
  batch.sequence = unroll.sequence();
  batch.incarnation = unroll.incarnation();
  batch.policy_version = unroll.policy_version();
  ScoreOutput out;
  out.global_rewards = response->mutable_global_rewards()->mutable_data();
  out.contributions = response->mutable_contributions()->mutable_data();
  out.shares = response->mutable_shares()->mutable_data();
  out.agent_rewards = response->mutable_agent_rewards()->mutable_data();
  if (scorer_->ReturnsInfluences()) {
    response->mutable_influences()->Resize(count * n * n, 0.0f);
    out.influences = response->mutable_influences()->mutable_data();
  }
  ScoreSeconds seconds{};
  out.seconds = &seconds;
  // A retried Score (same actor incarnation and sequence as its last one:
  // the first answer was lost) is answered again but not counted again.
  bool dry_run = request->dry_run();
  if (!dry_run && unroll.incarnation() != 0) {
    absl::MutexLock lock(&scored_mu_);
    auto it = last_scored_.find(unroll.actor_id());
    if (it == last_scored_.end()) {
      // Past the cap a new id is scored but not tracked (its retries would
      // count again): ids a client invents must not grow the map for ever.
      if (last_scored_.size() < max_tracked_actors_) {
        last_scored_.emplace(unroll.actor_id(), std::make_pair(unroll.incarnation(), unroll.sequence()));
        std::fprintf(stderr, "reward_server: first Score from %s (%s)\n",
                     absl::CHexEscape(unroll.actor_id()).c_str(), PeerIdentity(*context).c_str());
      }
    } else if (it->second.first == unroll.incarnation() && unroll.sequence() <= it->second.second) {
      dry_run = true;
      ++requests_repeated_;
    } else {
      it->second = {unroll.incarnation(), unroll.sequence()};
    }
  }
  if (absl::Status status = scorer_->Score(batch, dry_run, out); !status.ok()) {
    if (!dry_run && unroll.incarnation() != 0) {
      absl::MutexLock lock(&scored_mu_);
      last_scored_.erase(unroll.actor_id());  // Not scored: its retry must count.
    }
    ++requests_rejected_;
    return ToGrpcStatus(status);
  }
  if (!dry_run) transitions_scored_ += count;
  ++requests_served_;
  for (int p = 0; p < kNumScorePhases; ++p) score_seconds_[p]->Increment(seconds[p]);
  handler_seconds_->Increment(std::chrono::duration<double>(std::chrono::steady_clock::now() - entered).count());
  return grpc::Status::OK;
}

grpc::Status RewardServiceImpl::GetStats(grpc::ServerContext*, const v1::GetStatsRequest*,
                                         v1::RewardStats* response) {
  *response = Stats();
  return grpc::Status::OK;
}

v1::RewardStats RewardServiceImpl::Stats() const {
  v1::RewardStats stats;
  v1::RewardStats* response = &stats;
  response->set_reward_kind(reward_kind_);
  response->set_credit(config_.credit);
  response->set_permutation(std::string(PermutationName(config_.permutation)));
  response->set_beta(config_.beta);
  response->set_temperature(config_.temperature);
  response->set_scenario(std::string(scenario_->name()));
  response->set_num_agents(scenario_->num_agents());
  // Count kinds keep the count with their tables, across restarts.
  response->set_transitions_scored(scorer_->DurableTransitions().value_or(transitions_scored_.load()));
  response->set_requests_served(requests_served_.load());
  response->set_requests_rejected(requests_rejected_.load());
  response->set_requests_repeated(requests_repeated_.load());
  scorer_->FillStats(response);
  for (int p = 0; p < kNumScorePhases; ++p) {
    (*response->mutable_score_seconds())[ScorePhaseName(static_cast<ScorePhase>(p))] = score_seconds_[p]->value();
  }
  response->set_handler_seconds(handler_seconds_->value());
  response->set_kernels(nn::KernelsInUse());
  return stats;
}

grpc::Status RewardServiceImpl::Snapshot(grpc::ServerContext*, const v1::SnapshotRequest*,
                                         v1::SnapshotResponse* response) {
  if (snapshot_path_.empty()) {
    return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION,
                        "the server was started without --snapshot");
  }
  if (absl::Status status = scorer_->Save(snapshot_path_); !status.ok()) return ToGrpcStatus(status);
  struct stat info {};
  response->set_path(snapshot_path_);
  if (stat(snapshot_path_.c_str(), &info) == 0) response->set_bytes(info.st_size);
  return grpc::Status::OK;
}

}  // namespace imca::reward
