// The learner: wires flags to a Learner and serves LearnerService.
#include <cstdio>
#include <optional>
#include <thread>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/flags/usage.h"
#include "absl/strings/str_cat.h"
#include "base/json.h"
#include "env/env.h"
#include "env/scenario_flags.h"
#include "learner/algorithms/mappo/ppo_trainer.h"
#include "learner/learner.h"
#include "learner/learner_service.h"
#include "nn/blas_kernels.h"
#include "protocol/unroll_check.h"
#include "rpc/grpc_util.h"
#include "rpc/metrics_flags.h"
#include "rpc/service_flags.h"
#include "rpc/transport_flags.h"

ABSL_FLAG(std::string, run_dir, "", "run folder for metrics.csv and checkpoints/");
ABSL_FLAG(std::string, resume, "", "checkpoint directory to resume from");
ABSL_FLAG(bool, auto_resume, false,
          "resume from <run_dir>/checkpoints if it holds a checkpoint, else start fresh "
          "(for restarts under docker-compose or Kubernetes)");
namespace {
// Every default comes from the config structs: one definition per hyperparameter.
const imca::learner::LearnerConfig kDefaults;
}  // namespace

ABSL_FLAG(std::optional<int64_t>, steps, std::nullopt,
          "budget in joint env steps (0: until stopped); default: the algorithm's (--list)");
ABSL_FLAG(std::string, algo, imca::learner::AlgoName(kDefaults.algo),
          "mappo (on-policy PPO), maddpg (off-policy, replay buffer) or cmae (tabular; docs/learner.md)");
ABSL_FLAG(double, cmae_gamma, kDefaults.cmae.gamma, "cmae: discount of its Q-tables");
ABSL_FLAG(double, cmae_explore_lr, kDefaults.cmae.explore_lr, "cmae: the exploration tables' learning rate (alpha1)");
ABSL_FLAG(double, cmae_exploit_lr, kDefaults.cmae.exploit_lr, "cmae: the exploitation tables' learning rate (alpha2)");
ABSL_FLAG(int64_t, cmae_replay, kDefaults.cmae.replay, "cmae: replay capacity in joint transitions");
ABSL_FLAG(int64_t, cmae_episodes, kDefaults.cmae.total_episodes,
          "cmae: episodes over which acting moves from the exploration to the exploitation tables");
ABSL_FLAG(int, cmae_goal_samples, kDefaults.cmae.goal_samples, "cmae: replay states each goal is chosen among");
ABSL_FLAG(int, cmae_batch, kDefaults.cmae.batch, "cmae: transitions of each exploitation fit");
ABSL_FLAG(int, cmae_entropy_every, kDefaults.cmae.entropy_every, "cmae: goals between choices of the restricted space");
ABSL_FLAG(double, cmae_recip_t, kDefaults.cmae.recip_t, "cmae: reciprocal temperature of that choice");
ABSL_FLAG(int, cmae_tracked, kDefaults.cmae.tracked, "cmae: restricted spaces weighed at each choice");
ABSL_FLAG(int64_t, cmae_insert_threshold, kDefaults.cmae.insert_threshold,
          "cmae: a (state, joint action) seen this often enters the goal replay no more");
ABSL_FLAG(int64_t, cmae_max_table_mb, kDefaults.cmae.max_table_mb,
          "cmae: refuse a scenario whose tables could outgrow this many MB");
ABSL_FLAG(int, maddpg_hidden, kDefaults.maddpg.hidden, "maddpg: hidden layer width (actor and critic)");
ABSL_FLAG(double, maddpg_actor_lr, kDefaults.maddpg.actor_lr, "maddpg: actor Adam learning rate");
ABSL_FLAG(double, maddpg_critic_lr, kDefaults.maddpg.critic_lr, "maddpg: critic Adam learning rate");
ABSL_FLAG(double, maddpg_tau, kDefaults.maddpg.tau, "maddpg: soft target update rate per gradient step");
ABSL_FLAG(double, maddpg_max_grad_norm, kDefaults.maddpg.max_grad_norm, "maddpg: grad-norm clip per network");
ABSL_FLAG(double, maddpg_policy_reg, kDefaults.maddpg.policy_reg, "maddpg: weight of mean(logits^2) in the actor loss");
ABSL_FLAG(int, maddpg_batch, kDefaults.maddpg.batch_size, "maddpg: transitions per gradient step");
ABSL_FLAG(int64_t, maddpg_buffer, kDefaults.maddpg.buffer_transitions, "maddpg: replay capacity in joint transitions");
ABSL_FLAG(int64_t, maddpg_learning_starts, kDefaults.maddpg.learning_starts,
          "maddpg: transitions in the replay before the first update");
ABSL_FLAG(double, updates_per_step, kDefaults.maddpg.updates_per_step,
          "maddpg: gradient steps per joint env step; the learner takes no more data than this allows, so "
          "actors are slowed to it");
ABSL_FLAG(bool, maddpg_share, kDefaults.maddpg.share_parameters,
          "maddpg: one actor and one critic (agent id in the input) for all agents; false: one of each per agent");
ABSL_FLAG(std::optional<int64_t>, batch_steps, std::nullopt,
          "joint env steps per iteration (mappo: the PPO batch; maddpg: between policy publications); default: "
          "the scenario's (--list)");
ABSL_FLAG(bool, deterministic, kDefaults.deterministic,
          "add each batch's unrolls in (actor id, sequence) order once it is whole, not as they arrive: with the "
          "reward server's --deterministic, a run is a function of its configuration (needs --synchronous)");
ABSL_FLAG(std::optional<int>, actors, std::nullopt,
          "actors collecting for a synchronous learner: each policy version asks each for batch_steps / actors "
          "env steps; default: the algorithm's (--list)");
ABSL_FLAG(int, epochs, kDefaults.ppo.epochs, "PPO epochs per iteration");
ABSL_FLAG(int, minibatches, kDefaults.ppo.minibatches, "PPO minibatches per epoch");
ABSL_FLAG(std::optional<double>, lr, std::nullopt, "Adam learning rate (default: the scenario's; --list)");
ABSL_FLAG(double, entropy_coef, kDefaults.ppo.entropy_coef, "entropy bonus coefficient");
ABSL_FLAG(double, clip, kDefaults.ppo.clip, "PPO ratio clip");
ABSL_FLAG(double, value_coef, kDefaults.ppo.value_coef, "weight of the value loss");
ABSL_FLAG(double, max_grad_norm, kDefaults.ppo.max_grad_norm, "gradient-norm clip (per optimiser)");
ABSL_FLAG(double, gamma, kDefaults.gamma, "extrinsic discount");
ABSL_FLAG(double, gamma_int, kDefaults.gamma_int, "intrinsic discount");
ABSL_FLAG(double, lambda, kDefaults.lambda, "GAE lambda");
ABSL_FLAG(double, intrinsic_coef, kDefaults.intrinsic_coef, "c_int: weight of the intrinsic advantage");
ABSL_FLAG(int, hidden, kDefaults.ppo.hidden, "hidden layer width");
ABSL_FLAG(std::string, objective, imca::learner::PpoObjectiveName(kDefaults.ppo.objective),
          "what the PPO clip is measured against: behaviour (the actor's recorded policy) or "
          "decoupled (a proximal policy recomputed by the learner; behaviour only as importance weight)");
ABSL_FLAG(bool, layer_norm, kDefaults.ppo.layer_norm,
          "LayerNorm on the input and after every hidden layer (actor and critic)");
ABSL_FLAG(std::optional<bool>, separate_optimizers, std::nullopt,
          "one Adam (and grad-norm clip) for the actor, one for the critic; false: one over both (default: the "
          "scenario's; --list)");
ABSL_FLAG(int, value_heads, kDefaults.ppo.value_heads,
          "2: extrinsic and intrinsic value heads; 1: one head on extrinsic + intrinsic_coef * intrinsic "
          "(3: with --edti)");
ABSL_FLAG(bool, edti, kDefaults.edti,
          "EDTI's value of interaction from the unrolls' influences (reward server --reward edti); the critic "
          "gets a third head (--value_heads is then 3); docs/baselines.md");
ABSL_FLAG(double, edti_tv, kDefaults.edti_coefficients.tv,
          "edti: coefficient of the transition term (EDTI's gamma_coor_tv)");
ABSL_FLAG(double, edti_tv_ext, kDefaults.edti_coefficients.tv_ext,
          "edti: weight of the partner's extrinsic value (gamma_coor_tv_e)");
ABSL_FLAG(double, edti_tv_int, kDefaults.edti_coefficients.tv_int,
          "edti: weight of the partner's curiosity value (gamma_coor_tv_c)");
ABSL_FLAG(double, edti_partner, kDefaults.edti_coefficients.partner,
          "edti: coefficient of the partner-reward term (gamma_coor_r)");
ABSL_FLAG(double, edti_partner_ext, kDefaults.edti_coefficients.partner_ext,
          "edti: weight of the partner's extrinsic reward (gamma_coor_r_e)");
ABSL_FLAG(double, edti_partner_int, kDefaults.edti_coefficients.partner_int,
          "edti: weight of the partner's curiosity reward (gamma_coor_r_c)");
ABSL_FLAG(std::string, critic_input, imca::learner::CriticInputName(kDefaults.critic_input),
          "the centralised critic's input besides the agent id: state (global state) or joint_obs "
          "(all agents' observations)");
ABSL_FLAG(std::string, time_limit, imca::learner::TimeLimitName(kDefaults.time_limit),
          "the step limit for the returns: bootstrap (truncation) or terminal (no bootstrap)");
ABSL_FLAG(std::optional<bool>, synchronous, std::nullopt,
          "train each iteration only on unrolls of the policy it starts from, each actor acting batch_steps / "
          "actors steps per version (default: true for mappo, false for maddpg)");
ABSL_FLAG(double, hidden_gain, kDefaults.ppo.hidden_gain, "orthogonal init gain of the hidden layers");
ABSL_FLAG(double, value_clip, kDefaults.ppo.value_clip,
          "clip value predictions to this distance from the iteration's start (normalised; 0: off)");
ABSL_FLAG(double, huber_delta, kDefaults.ppo.huber_delta, "Huber value loss delta (0: MSE)");
ABSL_FLAG(int, max_policy_lag, kDefaults.max_policy_lag,
          "mappo: drop unrolls older than this many policy versions (maddpg keeps every one)");
ABSL_FLAG(int, queue_capacity, kDefaults.queue_capacity,
          "unrolls waiting for training before PushUnrolls blocks the actors");
ABSL_FLAG(int, checkpoint_every, kDefaults.checkpoint_every, "iterations between checkpoints (0: not by iterations)");
ABSL_FLAG(double, checkpoint_seconds, kDefaults.checkpoint_seconds,
          "seconds between checkpoints (0: not by time); a killed learner loses at most this much training");
ABSL_FLAG(uint64_t, seed, kDefaults.seed, "seed of network initialisation and minibatch shuffling");
ABSL_FLAG(int, threads, kDefaults.threads, "LibTorch intra-op threads");
ABSL_FLAG(bool, concurrent_critic, kDefaults.ppo.concurrent_critic,
          "run each minibatch's critic pass on a second thread, concurrently with the actor's (same result)");
ABSL_FLAG(int64_t, max_batch_mb, kDefaults.max_batch_bytes / 1000000,
          "cap on an iteration's feature arrays in MB (batch_steps and unroll sizes over it are rejected)");
ABSL_FLAG(int, max_streams, imca::learner::LearnerServiceImpl::kDefaultMaxStreams,
          "unroll streams served at once (one per actor), and as many GetPolicy calls waiting for a new "
          "version; more end with RESOURCE_EXHAUSTED and retry");
ABSL_FLAG(double, linger_seconds, 2,
          "after the budget, keep serving this long so that actors in backoff learn it is done");
ABSL_FLAG(std::string, trained_log, "",
          "if set, append a CSV row per trained unroll (iteration, actor_id, incarnation, sequence, policy_version)");

namespace {

int Fail(const std::string& message) {
  std::fprintf(stderr, "learner: %s\n", message.c_str());
  return 2;
}

// The configuration the flags resolve: DefaultLearnerConfig for the
// scenario and --algo, then every flag given. Errors name the flag.
absl::StatusOr<imca::learner::LearnerConfig> ConfigFromFlags(absl::string_view scenario) {
  using namespace imca;
  absl::StatusOr<learner::Algo> algo = learner::ParseAlgo(absl::GetFlag(FLAGS_algo));
  if (!algo.ok()) return absl::InvalidArgumentError(absl::StrCat("--algo: ", algo.status().message()));
  learner::LearnerConfig config = learner::DefaultLearnerConfig(scenario, *algo);
  config.maddpg.hidden = absl::GetFlag(FLAGS_maddpg_hidden);
  config.maddpg.actor_lr = absl::GetFlag(FLAGS_maddpg_actor_lr);
  config.maddpg.critic_lr = absl::GetFlag(FLAGS_maddpg_critic_lr);
  config.maddpg.tau = absl::GetFlag(FLAGS_maddpg_tau);
  config.maddpg.max_grad_norm = absl::GetFlag(FLAGS_maddpg_max_grad_norm);
  config.maddpg.policy_reg = absl::GetFlag(FLAGS_maddpg_policy_reg);
  config.maddpg.batch_size = absl::GetFlag(FLAGS_maddpg_batch);
  config.maddpg.buffer_transitions = absl::GetFlag(FLAGS_maddpg_buffer);
  config.maddpg.learning_starts = absl::GetFlag(FLAGS_maddpg_learning_starts);
  config.maddpg.updates_per_step = absl::GetFlag(FLAGS_updates_per_step);
  config.maddpg.share_parameters = absl::GetFlag(FLAGS_maddpg_share);
  config.cmae.gamma = absl::GetFlag(FLAGS_cmae_gamma);
  config.cmae.explore_lr = absl::GetFlag(FLAGS_cmae_explore_lr);
  config.cmae.exploit_lr = absl::GetFlag(FLAGS_cmae_exploit_lr);
  config.cmae.replay = absl::GetFlag(FLAGS_cmae_replay);
  config.cmae.total_episodes = absl::GetFlag(FLAGS_cmae_episodes);
  config.cmae.goal_samples = absl::GetFlag(FLAGS_cmae_goal_samples);
  config.cmae.batch = absl::GetFlag(FLAGS_cmae_batch);
  config.cmae.entropy_every = absl::GetFlag(FLAGS_cmae_entropy_every);
  config.cmae.recip_t = absl::GetFlag(FLAGS_cmae_recip_t);
  config.cmae.tracked = absl::GetFlag(FLAGS_cmae_tracked);
  config.cmae.insert_threshold = absl::GetFlag(FLAGS_cmae_insert_threshold);
  config.cmae.max_table_mb = absl::GetFlag(FLAGS_cmae_max_table_mb);
  config.ppo.hidden = absl::GetFlag(FLAGS_hidden);
  if (const auto lr = absl::GetFlag(FLAGS_lr)) config.ppo.learning_rate = *lr;
  config.ppo.epochs = absl::GetFlag(FLAGS_epochs);
  config.ppo.minibatches = absl::GetFlag(FLAGS_minibatches);
  config.ppo.entropy_coef = absl::GetFlag(FLAGS_entropy_coef);
  config.ppo.clip = absl::GetFlag(FLAGS_clip);
  config.ppo.value_coef = absl::GetFlag(FLAGS_value_coef);
  config.ppo.max_grad_norm = absl::GetFlag(FLAGS_max_grad_norm);
  config.ppo.layer_norm = absl::GetFlag(FLAGS_layer_norm);
  if (const auto separate = absl::GetFlag(FLAGS_separate_optimizers)) config.ppo.separate_optimizers = *separate;
  config.ppo.value_heads = absl::GetFlag(FLAGS_value_heads);
  config.edti = absl::GetFlag(FLAGS_edti);
  if (config.edti) {
    if (config.ppo.value_heads == 1) {
      return absl::InvalidArgumentError("--value_heads 1 cannot be used with --edti (it needs 3)");
    }
    config.ppo.value_heads = 3;
  }
  config.edti_coefficients.tv = static_cast<float>(absl::GetFlag(FLAGS_edti_tv));
  config.edti_coefficients.tv_ext = static_cast<float>(absl::GetFlag(FLAGS_edti_tv_ext));
  config.edti_coefficients.tv_int = static_cast<float>(absl::GetFlag(FLAGS_edti_tv_int));
  config.edti_coefficients.partner = static_cast<float>(absl::GetFlag(FLAGS_edti_partner));
  config.edti_coefficients.partner_ext = static_cast<float>(absl::GetFlag(FLAGS_edti_partner_ext));
  config.edti_coefficients.partner_int = static_cast<float>(absl::GetFlag(FLAGS_edti_partner_int));
  config.ppo.hidden_gain = absl::GetFlag(FLAGS_hidden_gain);
  config.ppo.value_clip = absl::GetFlag(FLAGS_value_clip);
  config.ppo.huber_delta = absl::GetFlag(FLAGS_huber_delta);
  absl::StatusOr<learner::PpoObjective> objective = learner::ParsePpoObjective(absl::GetFlag(FLAGS_objective));
  if (!objective.ok()) return absl::InvalidArgumentError(absl::StrCat("--objective: ", objective.status().message()));
  config.ppo.objective = *objective;
  absl::StatusOr<learner::CriticInput> critic_input = learner::ParseCriticInput(absl::GetFlag(FLAGS_critic_input));
  if (!critic_input.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("--critic_input: ", critic_input.status().message()));
  }
  config.critic_input = *critic_input;
  absl::StatusOr<learner::TimeLimit> time_limit = learner::ParseTimeLimit(absl::GetFlag(FLAGS_time_limit));
  if (!time_limit.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("--time_limit: ", time_limit.status().message()));
  }
  config.time_limit = *time_limit;
  if (const auto synchronous = absl::GetFlag(FLAGS_synchronous)) config.synchronous = *synchronous;
  if (const auto actors = absl::GetFlag(FLAGS_actors)) config.actors = *actors;
  config.deterministic = absl::GetFlag(FLAGS_deterministic);
  config.seed = absl::GetFlag(FLAGS_seed);
  config.threads = absl::GetFlag(FLAGS_threads);
  config.ppo.concurrent_critic = absl::GetFlag(FLAGS_concurrent_critic);
  config.gamma = absl::GetFlag(FLAGS_gamma);
  config.gamma_int = absl::GetFlag(FLAGS_gamma_int);
  config.lambda = absl::GetFlag(FLAGS_lambda);
  config.intrinsic_coef = absl::GetFlag(FLAGS_intrinsic_coef);
  if (const auto batch_steps = absl::GetFlag(FLAGS_batch_steps)) config.batch_steps = *batch_steps;
  config.max_policy_lag = absl::GetFlag(FLAGS_max_policy_lag);
  config.queue_capacity = absl::GetFlag(FLAGS_queue_capacity);
  if (const auto steps = absl::GetFlag(FLAGS_steps)) config.budget_steps = *steps;
  config.run_dir = absl::GetFlag(FLAGS_run_dir);
  config.trained_log = absl::GetFlag(FLAGS_trained_log);
  config.checkpoint_every = absl::GetFlag(FLAGS_checkpoint_every);
  config.checkpoint_seconds = absl::GetFlag(FLAGS_checkpoint_seconds);
  const int64_t max_batch_mb = absl::GetFlag(FLAGS_max_batch_mb);
  if (max_batch_mb < 1 || max_batch_mb > (int64_t{1} << 30)) {
    return absl::InvalidArgumentError("--max_batch_mb must be in [1, 2^30]");
  }
  config.max_batch_bytes = max_batch_mb * 1000 * 1000;
  return config;
}

// The training configuration as flag name: value (what --print_config
// prints and --list gives per scenario): passed back as flags, it resolves
// to the same configuration.
std::string ConfigJson(const imca::learner::LearnerConfig& c) {
  using namespace imca;
  JsonObject json;
  json.Add("algo", learner::AlgoName(c.algo))
      .Add("steps", c.budget_steps)
      .Add("batch_steps", c.batch_steps)
      .Add("synchronous", c.synchronous)
      .Add("actors", c.actors)
      .Add("deterministic", c.deterministic)
      .Add("max_policy_lag", c.max_policy_lag)
      .Add("queue_capacity", c.queue_capacity)
      .Add("max_batch_mb", c.max_batch_bytes / 1000000)
      .Add("seed", c.seed)
      .Add("threads", c.threads)
      .Add("hidden", c.ppo.hidden)
      .AddExact("lr", c.ppo.learning_rate)
      .Add("separate_optimizers", c.ppo.separate_optimizers)
      .Add("epochs", c.ppo.epochs)
      .Add("minibatches", c.ppo.minibatches)
      .AddExact("entropy_coef", c.ppo.entropy_coef)
      .AddExact("clip", c.ppo.clip)
      .AddExact("value_coef", c.ppo.value_coef)
      .AddExact("max_grad_norm", c.ppo.max_grad_norm)
      .Add("objective", learner::PpoObjectiveName(c.ppo.objective))
      .Add("layer_norm", c.ppo.layer_norm)
      .Add("value_heads", c.ppo.value_heads)
      .AddExact("hidden_gain", c.ppo.hidden_gain)
      .AddExact("value_clip", c.ppo.value_clip)
      .AddExact("huber_delta", c.ppo.huber_delta)
      .Add("concurrent_critic", c.ppo.concurrent_critic)
      .Add("critic_input", learner::CriticInputName(c.critic_input))
      .Add("time_limit", learner::TimeLimitName(c.time_limit))
      .AddExact("gamma", c.gamma)
      .AddExact("gamma_int", c.gamma_int)
      .AddExact("lambda", c.lambda)
      .AddExact("intrinsic_coef", c.intrinsic_coef)
      .Add("edti", c.edti)
      .AddExact("edti_tv", c.edti_coefficients.tv)
      .AddExact("edti_tv_ext", c.edti_coefficients.tv_ext)
      .AddExact("edti_tv_int", c.edti_coefficients.tv_int)
      .AddExact("edti_partner", c.edti_coefficients.partner)
      .AddExact("edti_partner_ext", c.edti_coefficients.partner_ext)
      .AddExact("edti_partner_int", c.edti_coefficients.partner_int)
      .Add("maddpg_hidden", c.maddpg.hidden)
      .AddExact("maddpg_actor_lr", c.maddpg.actor_lr)
      .AddExact("maddpg_critic_lr", c.maddpg.critic_lr)
      .AddExact("maddpg_tau", c.maddpg.tau)
      .AddExact("maddpg_max_grad_norm", c.maddpg.max_grad_norm)
      .AddExact("maddpg_policy_reg", c.maddpg.policy_reg)
      .Add("maddpg_batch", c.maddpg.batch_size)
      .Add("maddpg_buffer", c.maddpg.buffer_transitions)
      .Add("maddpg_learning_starts", c.maddpg.learning_starts)
      .AddExact("updates_per_step", c.maddpg.updates_per_step)
      .Add("maddpg_share", c.maddpg.share_parameters)
      .AddExact("cmae_gamma", c.cmae.gamma)
      .AddExact("cmae_explore_lr", c.cmae.explore_lr)
      .AddExact("cmae_exploit_lr", c.cmae.exploit_lr)
      .Add("cmae_replay", c.cmae.replay)
      .Add("cmae_episodes", c.cmae.total_episodes)
      .Add("cmae_goal_samples", c.cmae.goal_samples)
      .Add("cmae_batch", c.cmae.batch)
      .Add("cmae_entropy_every", c.cmae.entropy_every)
      .AddExact("cmae_recip_t", c.cmae.recip_t)
      .Add("cmae_tracked", c.cmae.tracked)
      .Add("cmae_insert_threshold", c.cmae.insert_threshold)
      .Add("cmae_max_table_mb", c.cmae.max_table_mb)
      .Add("checkpoint_every", c.checkpoint_every)
      .AddExact("checkpoint_seconds", c.checkpoint_seconds);
  return json.Text();
}

// Each algorithm's defaults per scenario (DefaultLearnerConfig).
std::string DefaultsJson() {
  using namespace imca;
  JsonObject algos;
  for (const std::string& name : learner::AlgoNames()) {
    JsonObject scenarios;
    for (const std::string& scenario : env::ScenarioNames()) {
      scenarios.Raw(scenario, ConfigJson(learner::DefaultLearnerConfig(scenario, *learner::ParseAlgo(name))));
    }
    algos.Raw(name, scenarios.Text());
  }
  return algos.Text();
}

// --list: one JSON object.
std::string ListJson() {
  using namespace imca;
  std::string columns;
  for (const learner::Column& c : learner::IterationColumns()) {
    absl::StrAppend(&columns, columns.empty() ? "" : ", ",
                    JsonObject()
                        .Add("name", c.name)
                        .Add("help", c.help)
                        .Raw("prometheus", c.family != nullptr ? JsonString(c.family) : "null")
                        .Raw("algorithm", c.algorithm != nullptr ? JsonString(c.algorithm) : "null")
                        .Add("wall_clock", c.wall_clock)
                        .Text());
  }
  return JsonObject()
             .Add("program", "learner")
             .Add("scenarios", env::ScenarioNames())
             .Add("algos", learner::AlgoNames())
             .Add("default_algo", learner::AlgoName(kDefaults.algo))
             .Add("objectives", learner::PpoObjectiveNames())
             .Add("critic_inputs", learner::CriticInputNames())
             .Add("time_limits", learner::TimeLimitNames())
             .Add("success_window", kDefaults.metrics_window)
             .Add("max_actor_ids", kDefaults.max_actor_ids)
             .Add("max_unroll_transitions", kMaxTransitions)
             .Add("exit_refused", kExitRefused)
             .Add("exit_misconfigured", kExitMisconfigured)
             .Raw("learner_defaults", DefaultsJson())
             .Raw("metrics_columns", absl::StrCat("[", columns, "]"))
             .Text() +
         "\n";
}

// Writes the learner's status record (--status_file, read by a supervisor)
// if `path` is set; a failure is reported, not fatal.
void WriteLearnerStatus(const std::string& path, const imca::learner::Learner& learner) {
  if (path.empty()) return;  // Status() takes the learner's locks.
  const absl::Status written = imca::WriteStatusFile(path, learner.Status());
  if (!written.ok()) std::fprintf(stderr, "learner: status: %s\n", std::string(written.message()).c_str());
}

// Runs the learner's training to its end while its server answers: a
// watcher turns a shutdown signal (which only sets a flag) into Stop() and
// writes the status file every second, from its own thread, so that a
// wedged training thread shows as a growing seconds_stalled, not a silent
// file. After the budget it keeps answering up to `linger_seconds`, so that
// actors learn that it is done (OUT_OF_RANGE on push, done in GetStatus)
// instead of retrying. Returns Run()'s status.
absl::Status TrainWhileServing(imca::learner::Learner* learner, const std::string& status_file,
                               double linger_seconds) {
  using imca::ShutdownRequested;
  std::atomic<bool> finished{false};
  std::thread watcher([&] {
    auto last_status = std::chrono::steady_clock::time_point{};
    while (!finished.load() && !ShutdownRequested()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      if (std::chrono::steady_clock::now() - last_status > std::chrono::seconds(1)) {
        last_status = std::chrono::steady_clock::now();
        WriteLearnerStatus(status_file, *learner);
      }
    }
    learner->Stop();
  });
  const absl::Status run = learner->Run();
  finished.store(true);
  watcher.join();
  const auto linger_end = std::chrono::steady_clock::now() + std::chrono::duration<double>(linger_seconds);
  while (run.ok() && learner->Status().done() && !ShutdownRequested() &&
         std::chrono::steady_clock::now() < linger_end) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return run;
}

}  // namespace

int main(int argc, char** argv) {
  imca::nn::UseTheCpusBlasKernels(argv);  // First: it may re-execute the binary.
  absl::SetProgramUsageMessage("IMCA learner: multi-agent PPO or MADDPG over gRPC");
  absl::ParseCommandLine(argc, argv);
  using namespace imca;
  const absl::StatusOr<ServiceFlags> service_flags = ServiceFlagsFromFlags();
  if (!service_flags.ok()) return Fail(std::string(service_flags.status().message()));
  if (service_flags->list) {
    std::fputs(ListJson().c_str(), stdout);
    return 0;
  }

  if (absl::GetFlag(FLAGS_linger_seconds) < 0) return Fail("--linger_seconds must be >= 0");
  auto scenario = ScenarioFromFlags();
  if (!scenario.ok()) return Fail(std::string(scenario.status().message()));

  absl::StatusOr<learner::LearnerConfig> resolved = ConfigFromFlags((*scenario)->name());
  if (!resolved.ok()) return Fail(std::string(resolved.status().message()));
  learner::LearnerConfig config = *std::move(resolved);
  if (service_flags->print_config) {
    // Validated as a start would be, without a run folder to create.
    learner::LearnerConfig check = config;
    check.run_dir.clear();
    check.trained_log.clear();
    auto checked = learner::Learner::Create(scenario->get(), check);
    if (!checked.ok()) return Fail(std::string(checked.status().message()));
    std::printf("%s\n", ConfigJson(config).c_str());
    return 0;
  }
  absl::StatusOr<ServerOptions> server_options = ServerOptionsFromFlags();
  if (!server_options.ok()) return Fail(std::string(server_options.status().message()));
  const int max_streams = absl::GetFlag(FLAGS_max_streams);
  if (max_streams < 1) return Fail("--max_streams must be >= 1");
  auto learner = learner::Learner::Create(scenario->get(), config);
  if (!learner.ok()) return Fail(std::string(learner.status().message()));
  const absl::StatusOr<std::string> resume =
      learner::ResumeFolder(absl::GetFlag(FLAGS_resume), absl::GetFlag(FLAGS_auto_resume), config.run_dir);
  if (!resume.ok()) return Fail(std::string(resume.status().message()));
  if (!resume->empty()) {
    if (absl::Status restored = (*learner)->Restore(*resume); !restored.ok()) {
      return Fail(absl::StrCat("--resume: ", restored.message()));
    }
    std::fprintf(stderr, "learner: resumed at policy version %lld\n",
                 static_cast<long long>((*learner)->Status().policy_version()));
  }

  learner::LearnerServiceImpl service(learner->get(), max_streams);
  ProcessMetrics process_metrics(RpcMetrics::Side::kServer, {v1::LearnerService::service_full_name()});
  server_options->rpc_metrics = &process_metrics.rpc;
  auto metrics_server = process_metrics.Serve("learner", {&(*learner)->metrics(), &service.metrics()});
  if (!metrics_server.ok()) return Fail(std::string(metrics_server.status().message()));
  InstallShutdownSignalHandlers();
  int port = 0;
  auto server = ServeFromFlags(kDefaultLearnerAddress, {&service}, *server_options, &port);
  if (!server.ok()) return Fail(std::string(server.status().message()));
  std::fprintf(stderr, "learner: serving on port %d (%s)\n", port,
               TransportSummary(server_options->transport, /*server=*/true).c_str());

  const std::string& status_file = service_flags->status_file;
  const absl::Status run = TrainWhileServing(learner->get(), status_file, absl::GetFlag(FLAGS_linger_seconds));
  (*server)->Shutdown(DeadlineIn(std::chrono::seconds(3)));
  WriteLearnerStatus(status_file, **learner);
  if (!run.ok()) return Fail(absl::StrCat("training failed: ", run.message()));
  const v1::LearnerStatus status = (*learner)->Status();
  std::fprintf(stderr, "learner: stopped at %lld env steps, policy version %lld\n",
               static_cast<long long>(status.env_steps()),
               static_cast<long long>(status.policy_version()));
  return status.done() ? 0 : service_flags->signal_exit_code;
}
