#ifndef IMCA_ACTOR_ACTOR_H_
#define IMCA_ACTOR_ACTOR_H_

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"
#include "common/env.h"
#include "common/featurizer.h"
#include "common/metrics.h"
#include "common/policy_mlp.h"
#include "common/rng.h"
#include "common/vec_env.h"
#include "imca/v1/learner_service.grpc.pb.h"
#include "imca/v1/reward_service.grpc.pb.h"

namespace imca::actor {

struct ActorConfig {
  std::string actor_id = "actor-0";
  int num_envs = 32;         // E training envs.
  int unroll_length = 16;    // T steps per unroll (coop_nav: 32; env::TuningOf).
  // Envs run with the same policy but never trained on. 200 evaluation
  // episodes (the learner's success window) span about 25k joint training
  // steps of coop_nav with 2 actors x 32 envs at 16, and 190k at 2
  // (docs/learner.md, "Success rate").
  int eval_envs = 16;
  uint64_t seed = 1;
  std::chrono::milliseconds rpc_timeout{10000};
  int unrolls_per_stream = 256;  // PushUnrolls streams are reopened after this many.
  // Longest wait for one unroll's ack (the learner delays acks while its
  // queue is full, by up to an iteration): past it the stream is cancelled,
  // logged, and the unroll resent on a new one.
  std::chrono::milliseconds ack_timeout{60000};
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
  //  "time": seconds since the epoch}.
  std::string status_file;
  std::chrono::milliseconds status_period{1000};
  // The channels are TLS: a failed call that reads as a failed handshake is
  // logged as one.
  bool tls = false;
};

// The defaults of an actor of `scenario`: ActorConfig's, joined with the
// scenario's tuning (env::TuningOf). The actor binary's flags override them.
ActorConfig DefaultActorConfig(absl::string_view scenario);

// Steps vectorised environments with a local copy of the newest policy, gets
// each unroll's per-agent intrinsic rewards from the reward server (one Score
// call per unroll) and streams the unroll to the learner. Every call has a
// deadline; UNAVAILABLE / DEADLINE_EXCEEDED lead to a reconnect with
// exponential backoff, and the unroll in hand is kept and sent again (its
// Score retried if it had no answer, its push resent under the same
// incarnation and sequence number if it had no ack: the learner drops a
// resend it already accepted). So a restart of the reward server or the
// learner loses none of this actor's data, and this actor's own death loses
// at most the unroll in hand. Not thread-safe: one thread calls Run().
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

  // Acts until a shutdown signal arrives or the learner reports its budget
  // done. Blocks. Returns OK on either; INTERNAL if the learner publishes a
  // policy that does not fit this scenario; FAILED_PRECONDITION if a
  // synchronous learner asks for a share of env steps that is not a whole
  // number of this actor's unrolls (sync_unrolls -1).
  absl::Status Run();

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
  // Fetches a newer policy if there is one. With `wait`, retries until one
  // is available (or shutdown). Returns false if none is available.
  bool RefreshPolicy(bool wait);
  // Blocks (long-polling GetPolicy) until the learner publishes a version
  // >= min_version, or goes back to an older one (a restart from an older
  // checkpoint). Returns false on shutdown or when the learner is done.
  bool AwaitPolicy(int64_t min_version);
  // Both of the above: GetPolicy(min_version), retrying errors with backoff
  // if `retry`; with `until_newer`, long-polls until a version >= min_version
  // arrives instead of returning true on "not modified".
  bool FetchPolicy(int64_t min_version, bool retry, bool until_newer);
  // Makes `policy` the acting policy; false (and policy_error_ set) if it
  // does not fit this scenario.
  bool Adopt(const v1::Policy& policy);
  void Rollout(v1::Unroll* unroll);
  void SampleActions(const int32_t* states, int num_envs, int32_t* actions, float* log_probs,
                     float* probs);
  absl::Status Score(v1::Unroll* unroll);
  // Sends *unroll (moved in and back out, not copied) and waits for its ack.
  // OK when the learner has it or dropped it for good (stale, a duplicate,
  // or acted with a policy the learner no longer has); UNAVAILABLE (and
  // other transport errors) when it must be sent again; INVALID_ARGUMENT
  // when the learner refuses it as invalid or over its cap; OUT_OF_RANGE
  // once the learner is done.
  absl::Status Push(v1::Unroll* unroll);
  // Writes config_.status_file if status_period has passed since the last
  // write (or `force`).
  void WriteStatus(const char* state, bool force);
  void CloseStream();
  bool LearnerDone();
  // Appends env 0's scored steps of `unroll` to the episode trace.
  void Trace(const v1::Unroll& unroll);
  void WriteTrace();

  const env::Scenario* scenario_;
  const ActorConfig config_;
  const env::Featurizer featurizer_;
  std::unique_ptr<v1::LearnerService::Stub> learner_;
  std::unique_ptr<v1::RewardService::Stub> reward_;
  std::optional<PolicyMlp> policy_;
  absl::Status policy_error_;
  std::chrono::steady_clock::time_point policy_failure_logged_{};
  env::VecEnv envs_;
  env::VecEnv eval_envs_;
  Rng rng_;

  // The ack watchdog: while Push waits for an ack, `ack_wait_since_` is set
  // and a thread started by Run() cancels the stream past ack_timeout.
  void WatchAcks();
  // Registers the actor's families in registry_ (from the constructor).
  void RegisterMetrics();
  absl::Mutex watch_mu_;
  bool watching_ ABSL_GUARDED_BY(watch_mu_) = false;
  std::optional<std::chrono::steady_clock::time_point> ack_wait_since_ ABSL_GUARDED_BY(watch_mu_);
  grpc::ClientContext* waiting_context_ ABSL_GUARDED_BY(watch_mu_) = nullptr;

  std::unique_ptr<grpc::ClientContext> stream_context_;
  std::unique_ptr<grpc::ClientReaderWriter<v1::PushUnrollsRequest, v1::PushUnrollsResponse>> stream_;
  int stream_unrolls_ = 0;
  const uint64_t incarnation_;
  int64_t sequence_ = 0;  // Of the newest unroll acted.
  int64_t unrolls_pushed_ = 0;
  int64_t unrolls_resent_ = 0;
  int64_t transitions_scored_ = 0;
  std::chrono::steady_clock::time_point status_written_{};
  // A stream that was up (had an ack) broke: the next one is a reconnect.
  bool stream_broken_ = false;

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
    std::vector<metrics::Counter*> refused;  // By v1::Rejection.
    metrics::Gauge* policy_version;
  };
  Counters counters_;
  int version_unrolls_ = 0;  // Unrolls pushed with the current policy version.
  int sync_unrolls_ = 0;     // In effect: config_.sync_unrolls, or as the policy asks.
  uint64_t learner_incarnation_ = 0;  // Of the learner that served policy_.

  // Scratch buffers, sized once.
  std::vector<float> obs_;
  std::vector<float> probs_;
  std::vector<int32_t> actions_;
  std::vector<float> log_probs_;
  std::vector<float> rewards_;
  std::vector<int32_t> reached_;
  std::unique_ptr<bool[]> terminated_;
  std::unique_ptr<bool[]> truncated_;
  std::vector<env::EpisodeEnd> finished_;

  // Episode trace (trace_file): CSV rows of env 0's current episode, of the
  // last finished one, and whether the current one lost an unroll.
  std::string trace_current_;
  std::string trace_last_;
  bool trace_gap_ = false;
  std::chrono::steady_clock::time_point trace_written_{};
};

}  // namespace imca::actor

#endif  // IMCA_ACTOR_ACTOR_H_
