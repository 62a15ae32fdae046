#ifndef IMCA_LEARNER_LEARNER_CONFIG_H_
#define IMCA_LEARNER_LEARNER_CONFIG_H_

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "learner/algorithms/mappo/gae.h"
#include "learner/algorithms/mappo/ppo_trainer.h"

namespace imca::learner {

// What the centralised critic sees besides the agent-id one-hot.
enum class CriticInput {
  kState,     // The global state encoding (featurizer global_dim).
  kJointObs,  // All agents' observations concatenated in agent order (n * obs_dim),
              // on-policy's MAPPO "share_obs".
};

// How the step limit ends an episode for the learner.
enum class TimeLimit {
  kBootstrap,  // Truncation: the value of the state reached bootstraps the return.
  kTerminal,   // As termination: no bootstrap (on-policy's MPE runner).
};

// "state" / "joint_obs", "bootstrap" / "terminal"; parsers return
// INVALID_ARGUMENT naming the accepted values.
std::string CriticInputName(CriticInput input);
std::vector<std::string> CriticInputNames();
absl::StatusOr<CriticInput> ParseCriticInput(const std::string& name);
std::string TimeLimitName(TimeLimit limit);
std::vector<std::string> TimeLimitNames();
absl::StatusOr<TimeLimit> ParseTimeLimit(const std::string& name);

// MADDPG for discrete actions (learner/algorithms/maddpg/maddpg.h, docs/learner.md
// "MADDPG"): the reference implementations' defaults (BASELINES.md 2) where
// our episodes allow them.
struct MaddpgConfig {
  int hidden = 64;                  // Two hidden ReLU layers, actor and critic.
  double actor_lr = 1e-2;           // Adam, both nets (reference 1e-2).
  double critic_lr = 1e-2;
  double tau = 0.01;                // Soft target update per gradient step.
  double max_grad_norm = 0.5;       // Per network.
  double policy_reg = 1e-3;         // * mean(logits^2) in the actor loss.
  int batch_size = 1024;            // Transitions per gradient step.
  int64_t buffer_transitions = 1000000;  // Joint transitions kept (FIFO).
  int64_t learning_starts = 25600;  // No update before the replay holds this many.
  // Gradient steps per joint env step inserted (the reference's one per 100
  // env steps). Enforced both ways: the learner takes no more unrolls than
  // the updates due so far allow (the queue fills and pushes wait, so the
  // actors slow down), and takes no update ahead of the data.
  double updates_per_step = 0.01;
  // One actor (the observation carries the agent id, as MAPPO's) and one
  // critic with an agent-id input, or n of each.
  bool share_parameters = true;
};

// CMAE as its released gridworld code runs it (learner/algorithms/cmae/cmae.h,
// BASELINES.md 3.1, docs/baselines.md "CMAE"): main.py's defaults and the
// flags its scripts pass (--tree_subspace --stochastic_select_subspace
// --mixed_explore); its discount is this struct's, not LearnerConfig::gamma.
struct CmaeConfig {
  double gamma = 0.95;
  double explore_lr = 0.1;         // alpha1: the exploration tables' learning rate.
  double exploit_lr = 0.05;        // alpha2: the exploitation tables'.
  int64_t replay = 400000;         // Transitions kept (replay_size).
  // Acting mixes the tables with weight episodes / total_episodes on the
  // exploitation side (1 from then on).
  int64_t total_episodes = 15000;
  int goal_samples = 1024;         // Replay states a goal is chosen among.
  int batch = 512;                 // Transitions of an exploitation fit.
  int entropy_every = 20;          // Goals between choices of the restricted space.
  double recip_t = 50;             // Reciprocal temperature of that choice.
  int tracked = 10;                // Restricted spaces taken off the queue per choice (subspace_q_size).
  // A (state, joint action) seen this often goes into the goal sampler's
  // replay no more (insert_data's th).
  int64_t insert_threshold = 10000;
  // Refuse a scenario whose tables could outgrow this (Cmae::TableBytes).
  int64_t max_table_mb = 4096;
};

// The learner's algorithm.
enum class Algo {
  kMappo,   // On-policy multi-agent PPO (learner/algorithms/mappo/mappo.h).
  kMaddpg,  // Off-policy MADDPG (learner/algorithms/maddpg/maddpg.h).
  kCmae,    // Tabular CMAE (learner/algorithms/cmae/cmae.h).
};
// "mappo" / "maddpg" / "cmae"; the parser returns INVALID_ARGUMENT naming them.
std::string AlgoName(Algo algo);
std::vector<std::string> AlgoNames();
absl::StatusOr<Algo> ParseAlgo(const std::string& name);

struct LearnerConfig {
  Algo algo = Algo::kMappo;
  // Of every algorithm: the seed of network initialisation and sampling
  // (minibatch shuffling, replay draws), and LibTorch's intra-op threads.
  uint64_t seed = 1;
  int threads = 1;
  PpoConfig ppo;                  // MAPPO only; its seed and threads are the two above.
  MaddpgConfig maddpg;            // MADDPG only; its discount is `gamma`.
  CmaeConfig cmae;                // CMAE only.
  CriticInput critic_input = CriticInput::kState;  // MAPPO only (MADDPG's critic: joint obs and actions).
  TimeLimit time_limit = TimeLimit::kBootstrap;
  // Synchronous collection: an iteration trains only on unrolls acted with
  // the policy it starts from (lag 0). Push refuses any other version, and
  // once batch_steps of the current version are queued, further unrolls of
  // it (both as "stale ..."). Each published policy asks every actor for
  // batch_steps / actors env steps of it (Policy.sync_steps_per_actor); an
  // actor acts them and waits for the next version. MADDPG's default is
  // asynchronous (DefaultLearnerConfig): it learns from a replay of any age.
  bool synchronous = true;
  // The actors that collect for a synchronous learner; batch_steps must be a
  // multiple of it. Fewer actors than this stall a synchronous learner
  // (each version waits for shares nobody acts); more waste the unrolls
  // refused once the batch is full.
  int actors = 2;
  // Deterministic batches (needs synchronous): each iteration's unrolls are
  // added to the algorithm, and their episodes to the metrics windows, in
  // (actor id, sequence, incarnation) order once the whole batch is in,
  // not as they arrive. With the reward server's --deterministic and the
  // actors' seeds fixed, a run is a function of its configuration
  // (docs/learner.md, "Deterministic runs").
  bool deterministic = false;
  // EDTI (docs/baselines.md): each agent's advantage gains that of EDTI's
  // value of interaction (EdtiInteractionRewards, learner/algorithms/mappo/gae.h, from the
  // unroll's influences and the critic's values of the influenced agents),
  // learned by a third value head (ppo.value_heads must be 3). Push refuses
  // unrolls without influences (INVALID_ARGUMENT naming unroll.influences).
  bool edti = false;
  EdtiCoefficients edti_coefficients;
  double gamma = 0.99;            // Extrinsic discount.
  double gamma_int = 0.99;        // Intrinsic discount.
  double lambda = 0.95;           // GAE lambda (both heads).
  double intrinsic_coef = 1.0;    // c_int in A = A_ext + c_int * A_int (MADDPG: r = r_ext + c_int r_int).
  // Joint env steps (T*E summed over unrolls) per iteration: MAPPO's batch,
  // MADDPG's interval between policy publications.
  int64_t batch_steps = 1024;
  int max_policy_lag = 4;         // Unrolls older than this many versions are dropped (on-policy only).
  int queue_capacity = 4;          // Unrolls waiting for training; Push blocks beyond it.
  // Distinct actor ids remembered (exactly-once bookkeeping, the status's
  // list); an unroll of one more is refused (RESOURCE_EXHAUSTED).
  int max_actor_ids = 1 << 16;
  int64_t budget_steps = 2000000;  // Stop after this many joint env steps (0: never).
  std::string run_dir;            // metrics.csv and checkpoints/ go here ("" = none).
  // If set, a CSV row per trained unroll (iteration, actor_id, incarnation,
  // sequence, policy_version); rows of iterations a restart rolled back are
  // dropped.
  std::string trained_log;
  // A checkpoint is written every checkpoint_every iterations and whenever
  // checkpoint_seconds have passed since the last one (0 turns either off),
  // and at the end: a killed learner loses at most that much training.
  int checkpoint_every = 50;
  double checkpoint_seconds = 30;
  int metrics_window = 200;       // Episodes in the success-rate / return windows.
  // Cap on an iteration's feature arrays (policy and critic inputs, and the
  // trainer's copy of them; see Learner::IterationBytes). Create() rejects a
  // batch_steps over it and Push() an unroll that would push a batch over it,
  // so a large map with large unrolls is an error, not an out-of-memory kill.
  int64_t max_batch_bytes = int64_t{8192} * 1000 * 1000;  // --max_batch_mb 8192
};

// The defaults of a learner of `scenario` trained by `algo`, in the order they
// join: this file's and PpoConfig's, the scenario's tuning (env::TuningOf,
// beside the scenario's spec), then MADDPG's asynchronous collection. The
// one definition every way of starting the learner resolves (the binary's
// flags override it, --list prints it per scenario).
LearnerConfig DefaultLearnerConfig(absl::string_view scenario, Algo algo);

}  // namespace imca::learner

#endif  // IMCA_LEARNER_LEARNER_CONFIG_H_
