#ifndef IMCA_LEARNER_LEARNER_CONFIG_H_
#define IMCA_LEARNER_LEARNER_CONFIG_H_

#include <any>
#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace imca::learner {

// How the step limit ends an episode for the learner.
enum class TimeLimit {
  kBootstrap,  // Truncation: the value of the state reached bootstraps the return.
  kTerminal,   // As termination: no bootstrap (on-policy's MPE runner).
};

// "bootstrap" / "terminal" (the flag's spelling; common/base/settings.h).
std::string TimeLimitName(TimeLimit limit);
std::vector<std::string> SettingChoices(TimeLimit);
bool AbslParseFlag(absl::string_view text, TimeLimit* limit, std::string* error);
std::string AbslUnparseFlag(TimeLimit limit);

// What every algorithm's learner shares: the service, collection, the
// budget, checkpoints, the returns. An algorithm's own settings are its own
// struct, in its folder, held in `options` (learner/algorithms/registry.h).
struct LearnerConfig {
  // A registered algorithm's name (learner/algorithms/algorithms.def);
  // empty: the first registered.
  std::string algo;
  // The algorithm's own settings, of the type its registry entry names; none:
  // that type's defaults (OptionsOf below).
  std::any options;
  // Of every algorithm: the seed of network initialisation and sampling
  // (minibatch shuffling, replay draws), and LibTorch's intra-op threads.
  uint64_t seed = 1;
  int threads = 1;
  TimeLimit time_limit = TimeLimit::kBootstrap;
  // Synchronous collection: an iteration trains only on unrolls acted with
  // the policy it starts from (lag 0). Push refuses any other version, and
  // once batch_steps of the current version are queued, further unrolls of
  // it (both as "stale ..."). Each published policy asks every actor for
  // batch_steps / actors env steps of it (Policy.sync_steps_per_actor); an
  // actor acts them and waits for the next version. An off-policy
  // algorithm's default may be asynchronous (its registry entry's defaults).
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
  double gamma = 0.99;            // Extrinsic discount.
  double gamma_int = 0.99;        // Intrinsic discount.
  double lambda = 0.95;           // GAE lambda (both heads).
  double intrinsic_coef = 1.0;    // c_int in A = A_ext + c_int * A_int (or r = r_ext + c_int r_int).
  // Joint env steps (T*E summed over unrolls) per iteration: an on-policy
  // algorithm's batch, an off-policy one's interval between publications.
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

// The settings every algorithm's learner shares (common/base/settings.h): type,
// flag, field of LearnerConfig, help. The flags --algo and --max_batch_mb
// (max_batch_bytes in MB) are learner_flags.cc's own; run_dir and
// trained_log are the binary's wiring, not settings.
#define IMCA_LEARNER_SETTINGS(X)                                                                                    \
  X(int64_t, steps, budget_steps, "budget in joint env steps (0: until stopped)")                                   \
  X(int64_t, batch_steps, batch_steps,                                                                              \
    "joint env steps per iteration (on-policy: the batch; off-policy: between policy publications)")                \
  X(bool, synchronous, synchronous,                                                                                 \
    "train each iteration only on unrolls of the policy it starts from, each actor acting batch_steps / actors "   \
    "steps per version")                                                                                            \
  X(int, actors, actors,                                                                                            \
    "actors collecting for a synchronous learner: each policy version asks each for batch_steps / actors env "     \
    "steps")                                                                                                        \
  X(bool, deterministic, deterministic,                                                                             \
    "add each batch's unrolls in (actor id, sequence) order once it is whole, not as they arrive: with the reward " \
    "server's --deterministic, a run is a function of its configuration (needs --synchronous)")                    \
  X(int, max_policy_lag, max_policy_lag,                                                                            \
    "on-policy algorithms: drop unrolls older than this many policy versions (off-policy ones keep every one)")    \
  X(int, queue_capacity, queue_capacity, "unrolls waiting for training before PushUnrolls blocks the actors")       \
  X(uint64_t, seed, seed, "seed of network initialisation and sampling (minibatch shuffling, replay draws)")        \
  X(int, threads, threads, "LibTorch intra-op threads")                                                             \
  X(::imca::learner::TimeLimit, time_limit, time_limit,                                                             \
    "the step limit for the returns: bootstrap (truncation) or terminal (no bootstrap)")                           \
  X(double, gamma, gamma, "extrinsic discount")                                                                     \
  X(double, gamma_int, gamma_int, "intrinsic discount")                                                             \
  X(double, lambda, lambda, "GAE lambda")                                                                           \
  X(double, intrinsic_coef, intrinsic_coef, "c_int: weight of the intrinsic advantage (or reward)")                 \
  X(int, checkpoint_every, checkpoint_every, "iterations between checkpoints (0: not by iterations)")               \
  X(double, checkpoint_seconds, checkpoint_seconds,                                                                 \
    "seconds between checkpoints (0: not by time); a killed learner loses at most this much training")

// The algorithm options `config` holds, if they are a T (else null).
template <typename T>
const T* OptionsIf(const LearnerConfig& config) {
  return std::any_cast<T>(&config.options);
}
// The T options `config` holds, or T's defaults if it holds none (or
// another type's, which the algorithm's Create refuses).
template <typename T>
const T& OptionsOf(const LearnerConfig& config) {
  static const T* const kDefaults = new T();
  const T* options = OptionsIf<T>(config);
  return options != nullptr ? *options : *kDefaults;
}
// The T options in `config`, made T's defaults first if it holds no T.
template <typename T>
T& MutableOptions(LearnerConfig* config) {
  if (std::any_cast<T>(&config->options) == nullptr) config->options = T();
  return *std::any_cast<T>(&config->options);
}

}  // namespace imca::learner

#endif  // IMCA_LEARNER_LEARNER_CONFIG_H_
