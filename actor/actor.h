#ifndef IMCA_ACTOR_ACTOR_H_
#define IMCA_ACTOR_ACTOR_H_

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "actor/credit_trace.h"
#include "actor/policy_client.h"
#include "actor/stop_signal.h"
#include "actor/unroll_sender.h"
#include "common/base/rng.h"
#include "common/env/env.h"
#include "common/env/vec_env.h"
#include "common/metrics/metrics.h"
#include "common/rpc/grpc_util.h"
#include "imca/v1/learner_service.grpc.pb.h"
#include "imca/v1/reward_service.grpc.pb.h"

namespace imca::actor {

struct ActorConfig {
  std::string actor_id = "actor-0";
  // E training envs of T steps per unroll: with the learner's synchronous
  // defaults each env's whole share of an iteration is one unroll (2 actors x
  // 16 envs x 32 steps = 1024; coop_nav's 2048 in 64-step unrolls,
  // env::TuningOf). Fewer envs running longer between updates learn more per
  // sample than more envs of shorter unrolls (docs/learner.md, "Defaults").
  int num_envs = 16;
  int unroll_length = 32;
  // Envs run with the same policy but never trained on: half the training
  // envs, so that they cost a third of the stepping. 200 evaluation episodes
  // (the learner's success window) span about 25k joint training steps of
  // coop_nav with 2 actors x 16 envs at 8, and 190k at 1 (docs/learner.md,
  // "Success rate").
  int eval_envs = 8;
  uint64_t seed = 1;
  std::chrono::milliseconds rpc_timeout{10000};
  int unrolls_per_stream = 256;  // PushUnrolls streams are reopened after this many.
  // Longest wait for one unroll's ack (the learner delays acks while its
  // queue is full, by up to an iteration): past it the stream is cancelled,
  // logged, and the unroll resent on a new one.
  std::chrono::milliseconds ack_timeout{60000};
  // Testing: a pause before each Score call, which changes the order in
  // which actors' calls reach the reward server and the learner (the
  // deterministic-run test gives actors different ones).
  std::chrono::milliseconds score_delay{0};
  // If set, the newest finished training episode of env 0 with its credit
  // (one CSV row per step and agent: episode, t, agent, cell, next_cell,
  // action, share, contribution, agent_reward, global_reward) is written here,
  // atomically, at most every trace_period and when Run() returns.
  std::string trace_file;
  std::chrono::seconds trace_period{10};
  // Synchronous collection (learner --synchronous): after this many unrolls
  // acted with one policy version, wait for a newer version before acting
  // again. 0: asynchronous, never wait. -1: as each policy asks
  // (Policy.sync_steps_per_actor / (num_envs x unroll_length) unrolls, or
  // asynchronously if it asks for none).
  int sync_unrolls = -1;
  // This process's incarnation (Unroll.incarnation); 0: draw a random one.
  uint64_t incarnation = 0;
  // If set, a one-line JSON progress record is written here (atomically) at
  // most every status_period and when Run() returns, for a supervisor:
  // {"actor_id", "incarnation", "unrolls_pushed", "unrolls_resent",
  //  "transitions_scored", "state": "acting"|"waiting_policy"|"retrying"|"done",
  //  "phase_seconds": {"acting", "scoring", "pushing", "choosing_policy"},
  //  "time": seconds since the epoch}.
  std::string status_file;
  std::chrono::milliseconds status_period{1000};
  // The channels are TLS: a failed call that reads as a failed handshake is
  // logged as one.
  bool tls = false;
};

// The learner algorithms (--algo) whose policies an actor acts with
// (learner/algorithms/algorithms.def, the first the default).
std::vector<std::string> ActorAlgoNames();

// The defaults of an actor of `scenario` collecting for a learner of `algo`
// (an unknown one: none of its own): ActorConfig's, joined with the
// scenario's tuning (env::TuningOf), then the collection the algorithm's loop
// needs (learner::AlgorithmsActing, beside its code). The actor binary's
// flags override them.
ActorConfig DefaultActorConfig(absl::string_view scenario, absl::string_view algo = "");

// Steps vectorised environments with a local copy of the newest policy, gets
// each unroll's per-agent intrinsic rewards from the reward server (one Score
// call per unroll) and streams the unroll to the learner. Every call has a
// deadline; UNAVAILABLE / DEADLINE_EXCEEDED lead to a reconnect with
// exponential backoff, and the unroll in hand is kept and sent again (its
// Score retried if it had no answer, its push resent under the same
// incarnation and sequence number if it had no ack: the learner drops a
// resend it already accepted). So a restart of the reward server or the
// learner loses none of this actor's data, and this actor's own death loses
// at most the unroll in hand.
//
// Its parts: a PolicyClient (the learner's policies), an UnrollSender (the
// unroll stream, its acks and their watchdog) and a CreditTrace; Run() moves
// the unroll in hand through the phases of Phase.
//
// Thread safety: one thread calls Run(); Stop() and metrics() may be called
// from any thread.
class Actor {
 public:
  // Errors: INVALID_ARGUMENT naming the field of `config` out of range
  // (num_envs, unroll_length, eval_envs, sync_unrolls, the timeouts, an
  // unroll over kMaxTransitions).
  static absl::Status Validate(const ActorConfig& config);
  // The actor after Validate(config); the constructor takes a valid config.
  static absl::StatusOr<std::unique_ptr<Actor>> Create(const env::Scenario* scenario, const ActorConfig& config,
                                                       std::shared_ptr<grpc::Channel> learner,
                                                       std::shared_ptr<grpc::Channel> reward_server);
  Actor(const env::Scenario* scenario, const ActorConfig& config,
        std::shared_ptr<grpc::Channel> learner, std::shared_ptr<grpc::Channel> reward_server);

  // Acts until Stop(), a shutdown signal, or the learner reports its budget
  // done. Blocks. Returns OK on any of these; INTERNAL if the learner
  // publishes a policy that does not fit this scenario; FAILED_PRECONDITION
  // if a synchronous learner asks for a share of env steps that is not a
  // whole number of this actor's unrolls (sync_unrolls -1); INVALID_ARGUMENT
  // if the learner rejects an unroll as invalid; the refusal of a call
  // (credentials: UNAUTHENTICATED, PERMISSION_DENIED).
  absl::Status Run();
  // Asks Run() to return: the call in flight is cancelled and the unroll in
  // hand dropped (as if the process had died). Thread-safe; returns at once.
  void Stop() { stop_.Stop(); }

  // The phases of the unroll in hand, in Run()'s order.
  enum class Phase {
    kActing,          // Rolling out a new unroll with the policy held.
    kScoring,         // Asking the reward server for its intrinsic rewards (again after a failure).
    kPushing,         // Sending it to the learner and waiting for its ack (again after a failure).
    kChoosingPolicy,  // Delivered: taking a newer policy, or waiting for one (synchronous).
    kDone,
  };
  static constexpr int kNumPhases = static_cast<int>(Phase::kDone);  // The timed ones.
  // "acting", "scoring", "pushing", "choosing_policy" ("" for kDone).
  static std::string PhaseName(Phase phase);

  int64_t unrolls_pushed() const { return unrolls_pushed_; }
  // Pushes sent again after a lost stream.
  int64_t unrolls_resent() const { return unrolls_resent_; }
  uint64_t incarnation() const { return incarnation_; }
  // Transitions whose Score was answered.
  int64_t transitions_scored() const { return transitions_scored_; }
  // The actor's Prometheus families (docs/metrics.md): env steps, episodes,
  // unrolls pushed, resent and refused by reason, reconnects, retries,
  // policy updates. Thread-safe.
  const metrics::Registry& metrics() const { return registry_; }

 private:
  // The policy client's check of a policy before it is taken: with
  // sync_unrolls -1, its synchronous share must be whole unrolls.
  absl::Status Admit(const v1::Policy& policy);
  void Rollout(v1::Unroll* unroll);
  // Actions of the policy held for states [num_envs][K]; `evaluation`: for
  // the evaluation envs (a tabular policy acts on its exploitation table).
  void SampleActions(const int32_t* states, int num_envs, bool evaluation, int32_t* actions, float* log_probs,
                     float* probs);
  absl::Status Score(v1::Unroll* unroll);
  // Sends *unroll (moved in and back out) through the sender. OK when the
  // learner has it or dropped it for good (stale, a duplicate, or acted with
  // a policy the learner no longer has: then the learner's policy is taken);
  // UNAVAILABLE (and other transport errors) when it must be sent again;
  // INVALID_ARGUMENT when the learner refuses it as invalid or over its cap;
  // OUT_OF_RANGE once the learner is done.
  absl::Status Push(v1::Unroll* unroll);
  // The phase after a failed Score or push: `retry` after a backoff if the
  // failure is transient; kDone (error_ set if it is an error) if not.
  Phase AfterFailure(const absl::Status& status, Phase retry, const char* peer, Backoff* backoff);
  // The phase after an unroll was delivered.
  Phase AfterDelivery(int64_t version_acted);
  // Writes config_.status_file if status_period has passed since the last
  // write (or `force`).
  void WriteStatus(v1::ActorStatus::State state, bool force);
  struct Counters;
  // Registers the actor's families in `registry`.
  static Counters RegisterMetrics(metrics::Registry* registry);

  const env::Scenario* scenario_;
  const ActorConfig config_;
  std::unique_ptr<v1::LearnerService::Stub> learner_;
  std::unique_ptr<v1::RewardService::Stub> reward_;
  StopSignal stop_;
  env::VecEnv envs_;
  env::VecEnv eval_envs_;
  Rng rng_;
  const uint64_t incarnation_;
  int64_t sequence_ = 0;  // Of the newest unroll acted.
  int64_t unrolls_pushed_ = 0;
  int64_t unrolls_resent_ = 0;
  int64_t transitions_scored_ = 0;
  absl::Status error_;  // Why Run() stops, if for an error not the policy client's.
  std::chrono::steady_clock::time_point status_written_{};

  metrics::Registry registry_;
  struct Counters {
    metrics::Counter* env_steps;
    metrics::Counter* episodes;
    metrics::Counter* transitions_scored;
    metrics::Counter* unrolls_pushed;
    metrics::Counter* unrolls_resent;
    metrics::Counter* reconnects;
    metrics::Counter* retries;
    metrics::Counter* policy_updates;
    std::vector<metrics::Counter*> phase_seconds;  // By Phase, before kDone.
    std::vector<metrics::Counter*> refused;        // By v1::Rejection.
    metrics::Gauge* policy_version;
  };
  Counters counters_;
  int version_unrolls_ = 0;  // Unrolls delivered that were acted with the current policy version.
  int sync_unrolls_ = 0;     // In effect: config_.sync_unrolls, or as the policy asks.
  bool policy_final_ = false;  // The policy in use is the learner's last (Policy.final): act no more.

  PolicyClient policies_;
  UnrollSender sender_;
  std::optional<CreditTrace> trace_;

  // Scratch buffers, sized once.
  std::vector<float> probs_;
  std::vector<int32_t> actions_;
  std::vector<float> log_probs_;
  std::vector<float> rewards_;
  std::vector<int32_t> reached_;
  std::unique_ptr<bool[]> terminated_;
  std::unique_ptr<bool[]> truncated_;
  std::vector<env::EpisodeEnd> finished_;
};

}  // namespace imca::actor

#endif  // IMCA_ACTOR_ACTOR_H_
