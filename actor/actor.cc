#include "actor/actor.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <thread>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/base/enum_names.h"
#include "common/base/lap.h"
#include "common/base/status_macros.h"
#include "common/protocol/policy_mlp.h"
#include "common/protocol/unroll_check.h"
#include "common/rpc/grpc_util.h"
#include "common/rpc/service_flags.h"
#include "common/rpc/transport.h"
#include "learner/algorithms/acting.h"

namespace imca::actor {

std::vector<std::string> ActorAlgoNames() {
  std::vector<std::string> names;
  for (const learner::AlgorithmActing& acting : learner::AlgorithmsActing()) names.push_back(acting.name);
  return names;
}

ActorConfig DefaultActorConfig(absl::string_view scenario, absl::string_view algo) {
  ActorConfig config;
  config.unroll_length = env::TuningOf(scenario).unroll_length.value_or(config.unroll_length);
  const std::vector<learner::AlgorithmActing>& algorithms = learner::AlgorithmsActing();
  const absl::string_view name = algo.empty() ? absl::string_view(algorithms.front().name) : algo;
  for (const learner::AlgorithmActing& acting : algorithms) {
    if (acting.name != name) continue;
    config.num_envs = acting.num_envs.value_or(config.num_envs);
    config.unroll_length = acting.unroll_length.value_or(config.unroll_length);
  }
  return config;
}

absl::Status Actor::Validate(const ActorConfig& config) {
  if (config.num_envs < 1) return absl::InvalidArgumentError("num_envs (--envs) must be >= 1");
  if (config.unroll_length < 1) return absl::InvalidArgumentError("unroll_length (--unroll_length) must be >= 1");
  if (config.eval_envs < 0) return absl::InvalidArgumentError("eval_envs (--eval_envs) must be >= 0");
  if (config.sync_unrolls < -1) {
    return absl::InvalidArgumentError("sync_unrolls (--sync_unrolls) must be >= 0, or -1 (as the learner's policy asks)");
  }
  if (int64_t{config.num_envs} * config.unroll_length > kMaxTransitions) {
    return absl::InvalidArgumentError(
        absl::StrCat("num_envs * unroll_length (--envs x --unroll_length) must be <= ", kMaxTransitions,
                     " (an unroll's transitions)"));
  }
  if (config.rpc_timeout.count() < 100 || config.ack_timeout.count() < 100) {
    return absl::InvalidArgumentError("rpc_timeout and ack_timeout (--rpc_timeout_ms, --ack_timeout_ms) must be >= 100 ms");
  }
  if (config.score_delay.count() < 0 || config.score_delay.count() > 60000) {
    return absl::InvalidArgumentError("score_delay (--score_delay_ms) must be in [0, 60000] ms");
  }
  return absl::OkStatus();
}

absl::StatusOr<std::unique_ptr<Actor>> Actor::Create(const env::Scenario* scenario, const ActorConfig& config,
                                                     std::shared_ptr<grpc::Channel> learner,
                                                     std::shared_ptr<grpc::Channel> reward_server) {
  IMCA_RETURN_IF_ERROR(Validate(config));
  return std::make_unique<Actor>(scenario, config, std::move(learner), std::move(reward_server));
}

Actor::Actor(const env::Scenario* scenario, const ActorConfig& config,
             std::shared_ptr<grpc::Channel> learner, std::shared_ptr<grpc::Channel> reward_server)
    : scenario_(scenario),
      config_(config),
      learner_(v1::LearnerService::NewStub(learner)),
      reward_(v1::RewardService::NewStub(reward_server)),
      envs_(scenario, config.num_envs, config.seed),
      eval_envs_(scenario, std::max(config.eval_envs, 1), config.seed ^ 0xe7a1e7a1e7a1ULL),
      rng_(ActionSamplingSeed(config.seed)),
      incarnation_(config.incarnation != 0 ? config.incarnation : RandomIncarnation()),
      counters_(RegisterMetrics(&registry_)),
      sync_unrolls_(std::max(config.sync_unrolls, 0)),
      policies_(learner_.get(), *scenario,
                PolicyClientOptions{config.actor_id, config.rpc_timeout, config.tls}, &stop_,
                [this](const v1::Policy& policy) { return Admit(policy); },
                [this] { WriteStatus(v1::ActorStatus::WAITING_POLICY, /*force=*/false); }),
      sender_(PushUnrollsOf(learner_.get()),
              UnrollSenderOptions{config.actor_id, config.unrolls_per_stream, config.ack_timeout,
                                  counters_.reconnects},
              &stop_) {
  if (!config.trace_file.empty()) trace_.emplace(config.trace_file, config.trace_period, config.actor_id);
  const int rows = std::max(config.num_envs, config.eval_envs) * scenario->num_agents();
  const int envs = std::max(config.num_envs, config.eval_envs);
  probs_.resize(static_cast<size_t>(rows) * scenario->num_actions());
  actions_.resize(rows);
  log_probs_.resize(rows);
  rewards_.resize(rows);
  reached_.resize(static_cast<size_t>(envs) * scenario->state_size());
  terminated_.reset(new bool[envs]);
  truncated_.reset(new bool[envs]);
}

namespace {

// The timed phases' names (Actor::PhaseName).
constexpr EnumName<Actor::Phase> kPhaseNames[] = {{Actor::Phase::kActing, "acting"},
                                                  {Actor::Phase::kScoring, "scoring"},
                                                  {Actor::Phase::kPushing, "pushing"},
                                                  {Actor::Phase::kChoosingPolicy, "choosing_policy"}};
static_assert(sizeof(kPhaseNames) / sizeof(kPhaseNames[0]) == Actor::kNumPhases);

}  // namespace

std::string Actor::PhaseName(Phase phase) { return NameOf(phase, kPhaseNames); }

Actor::Counters Actor::RegisterMetrics(metrics::Registry* registry) {
  using metrics::Type;
  Counters c;
  c.env_steps = &registry->AddCounter({"imca_actor_env_steps_total", Type::kCounter,
                                       "Joint environment steps acted (training environments)."});
  c.episodes = &registry->AddCounter({"imca_actor_episodes_total", Type::kCounter,
                                      "Training episodes finished."});
  c.transitions_scored = &registry->AddCounter({"imca_actor_transitions_scored_total", Type::kCounter,
                                                "Transitions whose Score the reward server answered."});
  c.unrolls_pushed = &registry->AddCounter({"imca_actor_unrolls_pushed_total", Type::kCounter,
                                            "Unrolls the learner acknowledged (taken or dropped for good)."});
  c.unrolls_resent = &registry->AddCounter({"imca_actor_unrolls_resent_total", Type::kCounter,
                                            "Unrolls sent again after a lost stream."});
  c.reconnects = &registry->AddCounter({"imca_actor_reconnects_total", Type::kCounter,
                                        "Unroll streams opened again after one that had been acknowledged broke."});
  c.retries = &registry->AddCounter({"imca_actor_retries_total", Type::kCounter,
                                     "Failed Score or push attempts retried with backoff."});
  c.policy_updates = &registry->AddCounter({"imca_actor_policy_updates_total", Type::kCounter,
                                            "Policies fetched and adopted."});
  c.policy_version = &registry->AddGauge({"imca_actor_policy_version", Type::kGauge,
                                          "Version of the policy the actor acts with (-1: none yet)."});
  c.policy_version->Set(-1);
  for (int p = 0; p < kNumPhases; ++p) {
    c.phase_seconds.push_back(&registry->AddCounter(
        {"imca_actor_phase_seconds_total", Type::kCounter,
         "Seconds in each phase of the actor's loop: acting, scoring, pushing, choosing_policy (synchronous: "
         "mostly waiting for the next policy)."},
        {{"phase", PhaseName(static_cast<Phase>(p))}}));
  }
  c.refused = registry->AddCounterPerValue(
      {"imca_actor_unrolls_refused_total", Type::kCounter, "Unrolls the learner refused or dropped, by reason."},
      "reason", RejectionReasons());
  return c;
}

absl::Status Actor::Admit(const v1::Policy& policy) {
  if (config_.sync_unrolls < 0) {
    // As the learner asks: its share of env steps in whole unrolls.
    const int64_t share = policy.sync_steps_per_actor();
    const int64_t unroll_steps = int64_t{config_.num_envs} * config_.unroll_length;
    if (share % unroll_steps != 0) {
      return absl::FailedPreconditionError(absl::StrCat(
          "the synchronous learner asks each actor for ", share, " env steps per policy version (its batch_steps / ",
          "actors), not a whole number of this actor's unrolls of --envs x --unroll_length = ", unroll_steps,
          " steps; change --envs or --unroll_length, or the learner's --batch_steps or --actors"));
    }
    sync_unrolls_ = static_cast<int>(share / unroll_steps);
  }
  version_unrolls_ = 0;  // A share starts with each policy taken.
  policy_final_ = policy.final();
  counters_.policy_updates->Increment();
  counters_.policy_version->Set(static_cast<double>(policy.version()));
  return absl::OkStatus();
}

void Actor::SampleActions(const int32_t* states, int num_envs, bool evaluation, int32_t* actions,
                          float* log_probs, float* probs) {
  const int n = scenario_->num_agents(), a_count = scenario_->num_actions();
  policies_.policy()->Probabilities(states, num_envs, evaluation, probs);
  for (int row = 0; row < num_envs * n; ++row) {
    const float* p = probs + row * a_count;
    const int u = SampleCategorical(p, a_count, rng_.UniformDouble());
    actions[row] = u;
    log_probs[row] = std::log(std::max(p[u], 1e-12f));
  }
}

void Actor::Rollout(v1::Unroll* u) {
  const int E = config_.num_envs, T = config_.unroll_length;
  const int n = scenario_->num_agents(), k = scenario_->state_size(), a_count = scenario_->num_actions();
  u->set_scenario(std::string(scenario_->name()));
  u->set_actor_id(config_.actor_id);
  u->set_policy_version(policies_.version());
  u->set_length(T);
  u->set_num_envs(E);
  u->set_num_agents(n);
  u->set_num_actions(a_count);
  u->set_state_size(k);
  u->set_scenario_fingerprint(scenario_->fingerprint());
  u->set_incarnation(incarnation_);
  u->set_sequence(++sequence_);
  u->mutable_states()->Reserve((T + 1) * E * k);
  u->mutable_next_states()->Reserve(T * E * k);
  u->mutable_actions()->Reserve(T * E * n);
  u->mutable_action_probs()->Reserve(T * E * n * a_count);
  for (int t = 0; t < T; ++t) {
    u->mutable_states()->Add(envs_.states(), envs_.states() + E * k);
    for (int e = 0; e < E; ++e) u->add_episode_ids(envs_.episode_id(e));
    SampleActions(envs_.states(), E, /*evaluation=*/false, actions_.data(), log_probs_.data(), probs_.data());
    u->mutable_actions()->Add(actions_.begin(), actions_.begin() + E * n);
    u->mutable_behaviour_log_probs()->Add(log_probs_.begin(), log_probs_.begin() + E * n);
    u->mutable_action_probs()->Add(probs_.begin(), probs_.begin() + E * n * a_count);
    envs_.Step(actions_.data(), rewards_.data(), terminated_.get(), truncated_.get(), reached_.data());
    u->mutable_rewards()->Add(rewards_.begin(), rewards_.begin() + E * n);
    u->mutable_next_states()->Add(reached_.begin(), reached_.begin() + E * k);
    for (int e = 0; e < E; ++e) {
      u->add_terminated(terminated_[e]);
      u->add_truncated(truncated_[e]);
    }
    if (config_.eval_envs > 0) {
      const int V = config_.eval_envs;
      SampleActions(eval_envs_.states(), V, /*evaluation=*/true, actions_.data(), log_probs_.data(), probs_.data());
      eval_envs_.Step(actions_.data(), rewards_.data(), terminated_.get(), truncated_.get(), reached_.data());
    }
  }
  u->mutable_states()->Add(envs_.states(), envs_.states() + E * k);
  counters_.env_steps->Increment(static_cast<double>(u->length()) * E);
  finished_.clear();
  envs_.TakeFinished(&finished_);
  counters_.episodes->Increment(static_cast<double>(finished_.size()));
  for (const env::EpisodeEnd& end : finished_) {
    u->add_episode_returns(end.team_return);
    u->add_episode_success(end.success);
  }
  finished_.clear();
  eval_envs_.TakeFinished(&finished_);
  for (const env::EpisodeEnd& end : finished_) {
    u->add_eval_returns(end.team_return);
    u->add_eval_success(end.success);
  }
}

absl::Status Actor::Score(v1::Unroll* unroll) {
  if (config_.score_delay.count() > 0) std::this_thread::sleep_for(config_.score_delay);
  v1::ScoreRequest request;
  // The reward server reads states, next states, actions, probabilities and
  // episode ids; swap the unroll in and out instead of copying it.
  request.mutable_unroll()->Swap(unroll);
  grpc::ClientContext context;
  context.set_deadline(DeadlineIn(config_.rpc_timeout));
  v1::ScoreResponse response;
  grpc::Status status;
  {
    const StopSignal::Call call(&stop_, &context);
    status = reward_->Score(&context, request, &response);
  }
  unroll->Swap(request.mutable_unroll());
  if (!status.ok()) return FromGrpcStatus(status);
  *unroll->mutable_intrinsic_rewards() = std::move(*response.mutable_agent_rewards());
  *unroll->mutable_credit_shares() = std::move(*response.mutable_shares());
  *unroll->mutable_global_rewards() = std::move(*response.mutable_global_rewards());
  *unroll->mutable_contributions() = std::move(*response.mutable_contributions());
  *unroll->mutable_influences() = std::move(*response.mutable_influences());
  const int64_t transitions = int64_t{unroll->length()} * unroll->num_envs();
  transitions_scored_ += transitions;
  counters_.transitions_scored->Increment(static_cast<double>(transitions));
  if (trace_.has_value()) trace_->Add(*unroll);
  return absl::OkStatus();
}

absl::Status Actor::Push(v1::Unroll* unroll) {
  absl::StatusOr<v1::PushUnrollsResponse> ack = sender_.Send(unroll);
  if (!ack.ok()) return ack.status();
  if (ack->rejection() != v1::REJECTION_NONE && v1::Rejection_IsValid(ack->rejection())) {
    counters_.refused[ack->rejection()]->Increment();
  }
  switch (ack->rejection()) {
    case v1::REJECTION_NONE:
    case v1::REJECTION_STALE:      // Dropped and counted by the learner.
    case v1::REJECTION_DUPLICATE:  // It had it already: the first ack was lost.
      return absl::OkStatus();
    case v1::REJECTION_AHEAD:
      // The learner restarted from an older checkpoint: this unroll's policy
      // is gone; act on with the learner's.
      policies_.Restart();
      return absl::OkStatus();
    default:  // REJECTION_INVALID, REJECTION_OVER_CAP, or one this actor does not know.
      return absl::InvalidArgumentError(absl::StrCat("learner rejected unroll: ", ack->error()));
  }
}

Actor::Phase Actor::AfterFailure(const absl::Status& status, Phase retry, const char* peer, Backoff* backoff) {
  if (absl::IsInvalidArgument(status)) {
    error_ = status;  // A bug, not a transient fault: say so loudly and stop.
    return Phase::kDone;
  }
  if (absl::IsOutOfRange(status) || stop_.stopped()) return Phase::kDone;  // Budget done, or asked to stop.
  if (IsRefusal(status)) {
    // Retrying with the same credentials cannot help: one line, and stop.
    error_ = absl::Status(status.code(), DescribeRpcFailure(peer, status, config_.tls));
    return Phase::kDone;
  }
  // Keep the unroll: score it again if it has no answer yet, resend it if it
  // has no ack.
  std::fprintf(stderr, "%s: %s; retrying\n", config_.actor_id.c_str(),
               DescribeRpcFailure(peer, status, config_.tls).c_str());
  WriteStatus(v1::ActorStatus::RETRYING, /*force=*/false);
  counters_.retries->Increment();
  if (policies_.LearnerDone()) return Phase::kDone;
  backoff->Wait([this] { return stop_.stopped(); });
  return retry;
}

Actor::Phase Actor::AfterDelivery(int64_t version_acted) {
  if (sync_unrolls_ > 0 && version_unrolls_ >= sync_unrolls_) {
    // Synchronous: this version's share is delivered; act next with the
    // policy the learner trains on it.
    WriteStatus(v1::ActorStatus::WAITING_POLICY, /*force=*/false);
    if (!policies_.Await(version_acted + 1)) return Phase::kDone;
  } else {
    policies_.Refresh(/*wait=*/false);
  }
  if (!policies_.error().ok()) return Phase::kDone;
  if (policies_.version() != version_acted) version_unrolls_ = 0;
  return Phase::kActing;
}

absl::Status Actor::Run() {
  std::fprintf(stderr, "%s: incarnation %016llx\n", config_.actor_id.c_str(),
               static_cast<unsigned long long>(incarnation_));
  WriteStatus(v1::ActorStatus::WAITING_POLICY, /*force=*/true);
  Backoff backoff;
  v1::Unroll unroll;  // The unroll in hand; reused: Clear() keeps the packed fields' capacity.
  int pushes = 0;     // Of the unroll in hand: more than one are resends.
  Phase phase = Phase::kActing;
  while (phase != Phase::kDone) {
    if (stop_.stopped()) break;
    Clock::time_point lap = Clock::now();
    const Phase timed = phase;
    switch (phase) {
      case Phase::kActing:
        // No policy: the first, or the learner went back and had none to give.
        // Waiting for one counts as choosing a policy.
        if (policies_.policy() == nullptr) {
          const bool got = policies_.Refresh(/*wait=*/true);
          counters_.phase_seconds[static_cast<int>(Phase::kChoosingPolicy)]->Increment(Lap(lap));
          if (!got) {
            phase = Phase::kDone;  // The policy client's error() says why, if not stopped.
            break;
          }
        }
        if (policy_final_) {
          phase = Phase::kDone;  // The learner's budget is trained: nothing acted now would be.
          break;
        }
        unroll.Clear();
        Rollout(&unroll);
        pushes = 0;
        phase = Phase::kScoring;
        break;
      case Phase::kScoring: {
        const absl::Status scored = Score(&unroll);
        phase = scored.ok() ? Phase::kPushing : AfterFailure(scored, Phase::kScoring, "reward server", &backoff);
        break;
      }
      case Phase::kPushing: {
        if (pushes++ > 0) {
          ++unrolls_resent_;
          counters_.unrolls_resent->Increment();
        }
        const absl::Status pushed = Push(&unroll);
        if (!pushed.ok()) {
          phase = AfterFailure(pushed, Phase::kPushing, "learner", &backoff);
          break;
        }
        ++unrolls_pushed_;
        counters_.unrolls_pushed->Increment();
        // It counts towards this version's share only if it was acted with
        // the version now in use: after REJECTION_AHEAD the actor went back
        // to the learner's older policy, whose share it has not started.
        version_unrolls_ = unroll.policy_version() == policies_.version() ? version_unrolls_ + 1 : 0;
        backoff.Reset();
        WriteStatus(v1::ActorStatus::ACTING, /*force=*/false);
        phase = Phase::kChoosingPolicy;
        break;
      }
      case Phase::kChoosingPolicy:
        phase = AfterDelivery(policies_.version());
        break;
      case Phase::kDone:
        break;
    }
    counters_.phase_seconds[static_cast<int>(timed)]->Increment(Lap(lap));
  }
  sender_.Close();
  if (trace_.has_value()) trace_->Flush();
  WriteStatus(v1::ActorStatus::DONE, /*force=*/true);
  // OK, unless something this actor cannot retry stopped it.
  return !error_.ok() ? error_ : policies_.error();
}

void Actor::WriteStatus(v1::ActorStatus::State state, bool force) {
  if (config_.status_file.empty()) return;
  const auto now = std::chrono::steady_clock::now();
  if (!force && now - status_written_ < config_.status_period) return;
  status_written_ = now;
  v1::ActorStatus status;
  status.set_actor_id(config_.actor_id);
  status.set_incarnation(incarnation_);
  status.set_unrolls_pushed(unrolls_pushed_);
  status.set_unrolls_resent(unrolls_resent_);
  status.set_transitions_scored(transitions_scored_);
  status.set_state(state);
  for (int p = 0; p < kNumPhases; ++p) {
    (*status.mutable_phase_seconds())[PhaseName(static_cast<Phase>(p))] = counters_.phase_seconds[p]->value();
  }
  const absl::Status written = WriteStatusFile(config_.status_file, status);
  if (!written.ok()) {
    std::fprintf(stderr, "%s: status: %s\n", config_.actor_id.c_str(), std::string(written.message()).c_str());
  }
}

}  // namespace imca::actor
