#include "actor/actor.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <thread>

#include <unistd.h>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/atomic_file.h"
#include "common/grpc_util.h"
#include "common/json.h"
#include "common/status_macros.h"
#include "common/transport.h"
#include "common/unroll_check.h"

namespace imca::actor {

ActorConfig DefaultActorConfig(absl::string_view scenario) {
  ActorConfig config;
  config.unroll_length = env::TuningOf(scenario).unroll_length.value_or(config.unroll_length);
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
      featurizer_(*scenario),
      learner_(v1::LearnerService::NewStub(learner)),
      reward_(v1::RewardService::NewStub(reward_server)),
      envs_(scenario, config.num_envs, config.seed),
      eval_envs_(scenario, std::max(config.eval_envs, 1), config.seed ^ 0xe7a1e7a1e7a1ULL),
      rng_(config.seed * 7919 + 17),
      incarnation_(config.incarnation != 0 ? config.incarnation : RandomIncarnation()),
      sync_unrolls_(std::max(config.sync_unrolls, 0)) {
  const int rows = std::max(config.num_envs, config.eval_envs) * scenario->num_agents();
  const int envs = std::max(config.num_envs, config.eval_envs);
  obs_.resize(static_cast<size_t>(rows) * featurizer_.obs_dim());
  probs_.resize(static_cast<size_t>(rows) * scenario->num_actions());
  actions_.resize(rows);
  log_probs_.resize(rows);
  rewards_.resize(rows);
  reached_.resize(static_cast<size_t>(envs) * scenario->state_size());
  terminated_.reset(new bool[envs]);
  truncated_.reset(new bool[envs]);
  RegisterMetrics();
}

void Actor::RegisterMetrics() {
  using metrics::Type;
  Counters& c = counters_;
  c.env_steps = &registry_.AddCounter({"imca_actor_env_steps_total", Type::kCounter,
                                       "Joint environment steps acted (training environments)."});
  c.episodes = &registry_.AddCounter({"imca_actor_episodes_total", Type::kCounter,
                                      "Training episodes finished."});
  c.transitions_scored = &registry_.AddCounter({"imca_actor_transitions_scored_total", Type::kCounter,
                                                "Transitions whose Score the reward server answered."});
  c.unrolls_pushed = &registry_.AddCounter({"imca_actor_unrolls_pushed_total", Type::kCounter,
                                            "Unrolls the learner acknowledged (taken or dropped for good)."});
  c.unrolls_resent = &registry_.AddCounter({"imca_actor_unrolls_resent_total", Type::kCounter,
                                            "Unrolls sent again after a lost stream."});
  c.reconnects = &registry_.AddCounter({"imca_actor_reconnects_total", Type::kCounter,
                                        "Unroll streams opened again after one that had been acknowledged broke."});
  c.retries = &registry_.AddCounter({"imca_actor_retries_total", Type::kCounter,
                                     "Failed Score or push attempts retried with backoff."});
  c.policy_updates = &registry_.AddCounter({"imca_actor_policy_updates_total", Type::kCounter,
                                            "Policies fetched and adopted."});
  c.policy_version = &registry_.AddGauge({"imca_actor_policy_version", Type::kGauge,
                                          "Version of the policy the actor acts with (-1: none yet)."});
  c.policy_version->Set(-1);
  c.refused = AddRejectionCounters(&registry_, {"imca_actor_unrolls_refused_total", Type::kCounter,
                                                "Unrolls the learner refused or dropped, by reason."});
}

bool Actor::RefreshPolicy(bool wait) {
  return FetchPolicy(policy_.has_value() ? policy_->version() + 1 : 0, /*retry=*/wait, /*until_newer=*/false);
}

bool Actor::AwaitPolicy(int64_t min_version) {
  return FetchPolicy(min_version, /*retry=*/true, /*until_newer=*/true);
}

bool Actor::FetchPolicy(int64_t min_version, bool retry, bool until_newer) {
  // A long poll waits on the learner for at most half the deadline.
  const int wait_ms =
      until_newer ? static_cast<int>(std::clamp<int64_t>(config_.rpc_timeout.count() / 2, 1, 5000)) : 0;
  Backoff backoff;
  while (!ShutdownRequested()) {
    WriteStatus("waiting_policy", /*force=*/false);
    grpc::ClientContext context;
    context.set_deadline(DeadlineIn(config_.rpc_timeout));
    v1::GetPolicyRequest request;
    request.set_min_version(min_version);
    request.set_wait_ms(wait_ms);
    v1::Policy policy;
    const grpc::Status status = learner_->GetPolicy(&context, request, &policy);
    if (!status.ok()) {
      const absl::Status failed = FromGrpcStatus(status);
      if (IsRefusal(failed)) {
        policy_error_ = absl::Status(failed.code(), DescribeRpcFailure("learner", failed, config_.tls));
        return false;
      }
      // Said once, then every 10 s: a wrong certificate must not look like
      // a learner that is still starting.
      if (const auto now = std::chrono::steady_clock::now(); now - policy_failure_logged_ > std::chrono::seconds(10)) {
        policy_failure_logged_ = now;
        std::fprintf(stderr, "%s: GetPolicy: %s; retrying\n", config_.actor_id.c_str(),
                     DescribeRpcFailure("learner", failed, config_.tls).c_str());
      }
      if (!retry || (until_newer && LearnerDone())) return false;
      backoff.Wait();
      continue;
    }
    backoff.Reset();
    if (policy.tensors_size() > 0) return Adopt(policy);
    if (policy_.has_value() &&
        (policy.version() < policy_->version() || policy.learner_incarnation() != learner_incarnation_)) {
      // Not modified, but the learner restarted from a checkpoint: older
      // than ours, or ours, without the unrolls of it the old one took.
      // Take whatever it has, and deliver that version's share anew.
      policy_.reset();
      min_version = 0;
      continue;
    }
    if (!until_newer) return true;  // Nothing newer: keep acting with ours.
    if (LearnerDone()) return false;
  }
  return false;
}

bool Actor::Adopt(const v1::Policy& policy) {
  absl::StatusOr<PolicyMlp> mlp = PolicyMlp::FromProto(policy);
  absl::Status fits = mlp.ok() ? mlp->Fits(featurizer_.obs_dim(), scenario_->num_actions(), scenario_->num_agents())
                               : mlp.status();
  if (!fits.ok()) {
    policy_error_ = absl::InternalError(
        absl::StrCat("learner's policy does not fit ", scenario_->name(), ": ", fits.message()));
    return false;
  }
  if (config_.sync_unrolls < 0) {
    // As the learner asks: its share of env steps in whole unrolls.
    const int64_t share = policy.sync_steps_per_actor();
    const int64_t unroll_steps = int64_t{config_.num_envs} * config_.unroll_length;
    if (share % unroll_steps != 0) {
      policy_error_ = absl::FailedPreconditionError(absl::StrCat(
          "the synchronous learner asks each actor for ", share, " env steps per policy version (its batch_steps / ",
          "actors), not a whole number of this actor's unrolls of --envs x --unroll_length = ", unroll_steps,
          " steps; change --envs or --unroll_length, or the learner's --batch_steps or --actors"));
      return false;
    }
    sync_unrolls_ = static_cast<int>(share / unroll_steps);
  }
  policy_ = *std::move(mlp);
  learner_incarnation_ = policy.learner_incarnation();
  version_unrolls_ = 0;  // A share starts with each policy taken.
  counters_.policy_updates->Increment();
  counters_.policy_version->Set(static_cast<double>(policy.version()));
  return true;
}

void Actor::SampleActions(const int32_t* states, int num_envs, int32_t* actions, float* log_probs,
                          float* probs) {
  const int n = scenario_->num_agents(), k = scenario_->state_size(), a_count = scenario_->num_actions();
  const int obs_dim = featurizer_.obs_dim();
  for (int e = 0; e < num_envs; ++e) {
    for (int a = 0; a < n; ++a) {
      featurizer_.Observe(states + e * k, a, &obs_[static_cast<size_t>(e * n + a) * obs_dim]);
    }
  }
  policy_->Probabilities(obs_.data(), num_envs * n, probs);
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
  u->set_policy_version(policy_->version());
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
    SampleActions(envs_.states(), E, actions_.data(), log_probs_.data(), probs_.data());
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
      SampleActions(eval_envs_.states(), V, actions_.data(), log_probs_.data(), probs_.data());
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
  v1::ScoreRequest request;
  // The reward server reads states, next states, actions, probabilities and
  // episode ids; swap the unroll in and out instead of copying it.
  request.mutable_unroll()->Swap(unroll);
  grpc::ClientContext context;
  context.set_deadline(DeadlineIn(config_.rpc_timeout));
  v1::ScoreResponse response;
  const grpc::Status status = reward_->Score(&context, request, &response);
  unroll->Swap(request.mutable_unroll());
  if (!status.ok()) return FromGrpcStatus(status);
  *unroll->mutable_intrinsic_rewards() = std::move(*response.mutable_agent_rewards());
  *unroll->mutable_credit_shares() = std::move(*response.mutable_shares());
  *unroll->mutable_global_rewards() = std::move(*response.mutable_global_rewards());
  *unroll->mutable_contributions() = std::move(*response.mutable_contributions());
  *unroll->mutable_influences() = std::move(*response.mutable_influences());
  return absl::OkStatus();
}

void Actor::CloseStream() {
  if (stream_ != nullptr) {
    stream_->WritesDone();
    stream_->Finish().ok();
  }
  stream_.reset();
  stream_context_.reset();
  stream_unrolls_ = 0;
}

absl::Status Actor::Push(v1::Unroll* unroll) {
  if (stream_ != nullptr && stream_unrolls_ >= config_.unrolls_per_stream) CloseStream();
  if (stream_ == nullptr) {
    stream_context_ = std::make_unique<grpc::ClientContext>();
    // A stream lives for at most unrolls_per_stream unrolls; this deadline
    // bounds how long a hung learner can hold this actor.
    stream_context_->set_deadline(DeadlineIn(std::chrono::minutes(10)));
    stream_ = learner_->PushUnrolls(stream_context_.get());
    stream_unrolls_ = 0;
    if (stream_broken_) counters_.reconnects->Increment();
    stream_broken_ = false;
  }
  v1::PushUnrollsRequest request;
  request.mutable_unroll()->Swap(unroll);
  v1::PushUnrollsResponse ack;
  {
    absl::MutexLock lock(&watch_mu_);
    ack_wait_since_ = std::chrono::steady_clock::now();
    waiting_context_ = stream_context_.get();
  }
  const bool sent = stream_->Write(request);
  unroll->Swap(request.mutable_unroll());
  const bool acked = sent && stream_->Read(&ack);
  {
    absl::MutexLock lock(&watch_mu_);
    ack_wait_since_.reset();
    waiting_context_ = nullptr;
  }
  if (!acked) {
    // A reconnect is a new stream after one that was up (had an ack), not
    // each retry while the learner is not there yet.
    stream_broken_ = stream_unrolls_ > 0;
    const grpc::Status status = stream_->Finish();
    stream_.reset();
    stream_context_.reset();
    return status.ok() ? absl::UnavailableError("learner closed the stream") : FromGrpcStatus(status);
  }
  ++stream_unrolls_;
  if (ack.rejection() != v1::REJECTION_NONE && v1::Rejection_IsValid(ack.rejection())) {
    counters_.refused[ack.rejection()]->Increment();
  }
  switch (ack.rejection()) {
    case v1::REJECTION_NONE:
    case v1::REJECTION_STALE:      // Dropped and counted by the learner.
    case v1::REJECTION_DUPLICATE:  // It had it already: the first ack was lost.
      return absl::OkStatus();
    case v1::REJECTION_AHEAD:
      // The learner restarted from an older checkpoint: this unroll's policy
      // is gone; act on with the learner's.
      policy_.reset();
      RefreshPolicy(/*wait=*/true);
      return absl::OkStatus();
    default:  // REJECTION_INVALID, REJECTION_OVER_CAP, or one this actor does not know.
      return absl::InvalidArgumentError(absl::StrCat("learner rejected unroll: ", ack.error()));
  }
}

bool Actor::LearnerDone() {
  grpc::ClientContext context;
  context.set_deadline(DeadlineIn(std::chrono::seconds(2)));
  v1::LearnerStatus status;
  return learner_->GetStatus(&context, v1::GetStatusRequest(), &status).ok() && status.done();
}

void Actor::WatchAcks() {
  absl::MutexLock lock(&watch_mu_);
  while (watching_) {
    watch_mu_.AwaitWithTimeout(absl::Condition(+[](bool* watching) { return !*watching; }, &watching_),
                               absl::Milliseconds(200));
    if (ack_wait_since_.has_value() && waiting_context_ != nullptr &&
        std::chrono::steady_clock::now() - *ack_wait_since_ > config_.ack_timeout) {
      std::fprintf(stderr, "%s: no ack from the learner for %lld ms; reconnecting\n", config_.actor_id.c_str(),
                   static_cast<long long>(config_.ack_timeout.count()));
      waiting_context_->TryCancel();
      waiting_context_ = nullptr;  // Once per wait.
    }
  }
}

absl::Status Actor::Run() {
  {
    absl::MutexLock lock(&watch_mu_);
    watching_ = true;
  }
  std::thread watchdog([this] { WatchAcks(); });
  struct StopWatchdog {
    Actor* self;
    std::thread* thread;
    ~StopWatchdog() {
      {
        absl::MutexLock lock(&self->watch_mu_);
        self->watching_ = false;
      }
      thread->join();
    }
  } stop_watchdog{this, &watchdog};
  std::fprintf(stderr, "%s: incarnation %016llx\n", config_.actor_id.c_str(),
               static_cast<unsigned long long>(incarnation_));
  WriteStatus("waiting_policy", /*force=*/true);
  if (!RefreshPolicy(/*wait=*/true)) {
    WriteStatus("done", /*force=*/true);
    return policy_error_;
  }
  Backoff backoff;
  v1::Unroll unroll;  // Reused: Clear() keeps the packed fields' capacity.
  // The unroll in hand: acted, and scored (or not yet), not yet delivered.
  bool in_hand = false, scored = false, sent_once = false;
  while (!ShutdownRequested()) {
    if (!in_hand) {
      if (!policy_.has_value() && !RefreshPolicy(/*wait=*/true)) break;  // policy_error_ says why, if not done.
      unroll.Clear();
      Rollout(&unroll);
      in_hand = true;
      scored = false;
      sent_once = false;
    }
    absl::Status status;
    if (!scored) {
      status = Score(&unroll);
      scored = status.ok();
      if (scored) {
        transitions_scored_ += int64_t{unroll.length()} * unroll.num_envs();
        counters_.transitions_scored->Increment(static_cast<double>(unroll.length()) * unroll.num_envs());
        if (!config_.trace_file.empty()) Trace(unroll);
      }
    }
    if (scored) {
      if (sent_once) {
        ++unrolls_resent_;
        counters_.unrolls_resent->Increment();
      }
      sent_once = true;
      status = Push(&unroll);
    }
    if (status.ok()) {
      in_hand = false;
      ++unrolls_pushed_;
      counters_.unrolls_pushed->Increment();
      // It counts towards this version's share only if it was acted with the
      // version now in use: after REJECTION_AHEAD the actor went back to the
      // learner's older policy, whose share it has not started.
      if (policy_.has_value() && unroll.policy_version() == policy_->version()) {
        ++version_unrolls_;
      } else {
        version_unrolls_ = 0;
      }
      backoff.Reset();
      WriteStatus("acting", /*force=*/false);
    } else if (absl::IsInvalidArgument(status)) {
      // A bug, not a transient fault: say so loudly and stop.
      WriteStatus("done", /*force=*/true);
      return status;
    } else if (absl::IsOutOfRange(status)) {
      break;  // The learner's budget is done.
    } else if (IsRefusal(status)) {
      // Retrying with the same credentials cannot help: one line, and stop
      // (closing the stream and writing the trace on the way out).
      policy_error_ =
          absl::Status(status.code(), DescribeRpcFailure(scored ? "learner" : "reward server", status, config_.tls));
      break;
    } else {
      // Keep the unroll: score it again if it has no answer yet, resend it
      // if it has no ack.
      std::fprintf(stderr, "%s: %s; retrying\n", config_.actor_id.c_str(),
                   DescribeRpcFailure(scored ? "learner" : "reward server", status, config_.tls).c_str());
      WriteStatus("retrying", /*force=*/false);
      counters_.retries->Increment();
      if (LearnerDone()) break;
      backoff.Wait();
      continue;
    }
    const int64_t acted = policy_.has_value() ? policy_->version() : -1;
    if (sync_unrolls_ > 0 && version_unrolls_ >= sync_unrolls_) {
      // Synchronous: this version's share is delivered; act next with the
      // policy the learner trains on it.
      WriteStatus("waiting_policy", /*force=*/false);
      if (!AwaitPolicy(acted + 1)) break;
    } else {
      RefreshPolicy(/*wait=*/false);
    }
    if (!policy_error_.ok()) break;
    if (!policy_.has_value() || policy_->version() != acted) version_unrolls_ = 0;
  }
  CloseStream();
  if (!config_.trace_file.empty()) WriteTrace();
  WriteStatus("done", /*force=*/true);
  return policy_error_;  // OK, unless a policy could not be had (e.g. credentials refused).
}

void Actor::WriteStatus(const char* state, bool force) {
  if (config_.status_file.empty()) return;
  const auto now = std::chrono::steady_clock::now();
  if (!force && now - status_written_ < config_.status_period) return;
  status_written_ = now;
  JsonObject fields;
  fields.Add("actor_id", config_.actor_id)
      .Add("incarnation", absl::StrFormat("%016x", incarnation_))
      .Add("unrolls_pushed", unrolls_pushed_)
      .Add("unrolls_resent", unrolls_resent_)
      .Add("transitions_scored", transitions_scored_)
      .Add("state", state);
  const absl::Status written = WriteStatusFile(config_.status_file, std::move(fields));
  if (!written.ok()) {
    std::fprintf(stderr, "%s: status: %s\n", config_.actor_id.c_str(), std::string(written.message()).c_str());
  }
}

void Actor::Trace(const v1::Unroll& u) {
  const int E = u.num_envs(), n = u.num_agents(), k = u.state_size();
  if (u.intrinsic_rewards_size() != int64_t{u.length()} * E * n) {
    trace_gap_ = true;  // A malformed response: the learner rejects the unroll too.
    return;
  }
  const bool diagnostics = u.contributions_size() == u.intrinsic_rewards_size() &&
                           u.global_rewards_size() * n == u.intrinsic_rewards_size() &&
                           u.credit_shares_size() == u.intrinsic_rewards_size();
  for (int t = 0; t < u.length(); ++t) {
    const int64_t i = int64_t{t} * E;  // Env 0 of step t.
    const int32_t* state = u.states().data() + i * k;
    const int32_t* next = u.next_states().data() + i * k;
    const int step = state[k - 1];  // The state's last entry is the episode's step count.
    if (step == 0) {
      trace_current_.clear();
      trace_gap_ = false;
    }
    for (int a = 0; a < n; ++a) {
      const int64_t j = i * n + a;
      absl::StrAppendFormat(&trace_current_, "%d,%d,%d,%d,%d,%d,%.6g,%.6g,%.6g,%.6g\n", u.episode_ids(i), step, a,
                            state[env::AgentIndex(a)], next[env::AgentIndex(a)], u.actions(j),
                            diagnostics ? u.credit_shares(j) : 0.0f, diagnostics ? u.contributions(j) : 0.0f,
                            u.intrinsic_rewards(j), diagnostics ? u.global_rewards(i) : 0.0f);
    }
    if (u.terminated(i) || u.truncated(i)) {
      if (!trace_gap_) trace_last_.swap(trace_current_);
      trace_current_.clear();
      trace_gap_ = false;
    }
  }
  if (!trace_last_.empty() && std::chrono::steady_clock::now() - trace_written_ >= config_.trace_period) {
    WriteTrace();
  }
}

void Actor::WriteTrace() {
  trace_written_ = std::chrono::steady_clock::now();
  if (trace_last_.empty()) return;
  const absl::Status written = WriteFileAtomically(
      config_.trace_file,
      absl::StrCat("episode,t,agent,cell,next_cell,action,share,contribution,agent_reward,global_reward\n",
                   trace_last_));
  if (!written.ok()) {
    std::fprintf(stderr, "%s: trace: %s\n", config_.actor_id.c_str(), std::string(written.message()).c_str());
  }
}

}  // namespace imca::actor
