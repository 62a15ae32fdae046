#include "learner/learner.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <map>
#include <tuple>

#include "absl/container/flat_hash_map.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/base/atomic_file.h"
#include "common/base/enum_names.h"
#include "common/base/lap.h"
#include "common/base/status_macros.h"
#include "common/nn/blas_kernels.h"
#include "common/nn/threads.h"
#include "common/protocol/policy_table.h"
#include "common/protocol/unroll_check.h"
#include "learner/algorithms/registry.h"

namespace imca::learner {
namespace {

namespace fs = std::filesystem;

template <typename T>
void PushWindow(std::deque<T>* window, T value, int limit) {
  window->push_back(value);
  while (static_cast<int>(window->size()) > limit) window->pop_front();
}

template <typename T>
double Mean(const std::deque<T>& values) {
  if (values.empty()) return 0;
  double sum = 0;
  for (T v : values) sum += v;
  return sum / values.size();
}

}  // namespace

namespace {

constexpr EnumName<TimeLimit> kTimeLimitNames[] = {{TimeLimit::kBootstrap, "bootstrap"},
                                                   {TimeLimit::kTerminal, "terminal"}};

}  // namespace

std::string TimeLimitName(TimeLimit limit) { return NameOf(limit, kTimeLimitNames); }
std::vector<std::string> SettingChoices(TimeLimit) { return Names(kTimeLimitNames); }
bool AbslParseFlag(absl::string_view text, TimeLimit* limit, std::string* error) {
  return ParseFlagName(text, kTimeLimitNames, limit, error);
}
std::string AbslUnparseFlag(TimeLimit limit) { return TimeLimitName(limit); }

absl::StatusOr<std::unique_ptr<Learner>> Learner::Create(const env::Scenario* scenario,
                                                         const LearnerConfig& config) {
  if (config.batch_steps < 1) return absl::InvalidArgumentError("batch_steps must be >= 1");
  if (config.actors < 1) return absl::InvalidArgumentError("actors must be >= 1");
  if (config.deterministic && !config.synchronous) {
    return absl::InvalidArgumentError(
        "deterministic needs synchronous collection (synchronous true): only then is each batch a fixed set of "
        "unrolls");
  }
  if (config.synchronous && config.batch_steps % config.actors != 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "batch_steps ", config.batch_steps, " is not a multiple of actors ", config.actors,
        " (a synchronous learner asks each actor for batch_steps / actors env steps per policy version)"));
  }
  if (config.budget_steps < 0) return absl::InvalidArgumentError("budget_steps must be >= 0 (0: no budget)");
  if (config.checkpoint_every < 0 || !(config.checkpoint_seconds >= 0)) {
    return absl::InvalidArgumentError("checkpoint_every and checkpoint_seconds must be >= 0");
  }
  if (config.max_policy_lag < 0) return absl::InvalidArgumentError("max_policy_lag must be >= 0");
  if (config.queue_capacity < 1) return absl::InvalidArgumentError("queue_capacity must be >= 1");
  IMCA_ASSIGN_OR_RETURN(const AlgorithmEntry* entry, Algorithms().Find(config.algo));
  LearnerConfig named = config;
  named.algo = entry->name;
  nn::SetTorchThreads(config.threads);  // Once per process (common/nn/threads.h).
  IMCA_ASSIGN_OR_RETURN(std::unique_ptr<Algorithm> algorithm, entry->create(scenario, named));
  auto learner = std::unique_ptr<Learner>(new Learner(scenario, named, std::move(algorithm)));
  if (config.max_batch_bytes < 1) return absl::InvalidArgumentError("max_batch_bytes must be >= 1");
  if (const int64_t bytes = learner->IterationBytes(config.batch_steps); bytes > config.max_batch_bytes) {
    return absl::InvalidArgumentError(absl::StrFormat(
        "batch_steps: an iteration of %d steps needs %.0f MB of features here, over the memory cap of %.0f MB "
        "(max_batch_bytes, --max_batch_mb)",
        config.batch_steps, bytes / 1e6, config.max_batch_bytes / 1e6));
  }
  if (!config.run_dir.empty()) {
    std::error_code error;
    fs::create_directories(fs::path(config.run_dir) / "checkpoints", error);
    if (error) {
      return absl::InternalError(absl::StrCat("cannot create ", config.run_dir, ": ", error.message()));
    }
  }
  learner->Publish();
  return learner;
}

namespace {

// The learner's families besides its metrics.csv columns (iteration_metrics.cc).
const metrics::Family kUnrollsReceived{"imca_learner_unrolls_received_total", metrics::Type::kCounter,
                                       "Unrolls accepted into the training queue."};
const metrics::Family kUnrollsDropped{"imca_learner_unrolls_dropped_total", metrics::Type::kCounter,
                                      "Unrolls refused or dropped, by reason (stale, ahead, over_cap, duplicate, "
                                      "invalid)."};
const metrics::Family kBatchesDropped{"imca_learner_batches_dropped_total", metrics::Type::kCounter,
                                      "Iterations whose batch the algorithm refused (non-finite advantages)."};
const metrics::Family kMinibatchesSkipped{"imca_learner_minibatches_skipped_total", metrics::Type::kCounter,
                                          "Minibatches whose loss or gradient was not finite (no step)."};
const metrics::Family kQueueDepth{"imca_learner_queue_depth", metrics::Type::kGauge,
                                  "Unrolls queued for training."};
const metrics::Family kQueuedSteps{"imca_learner_queued_env_steps", metrics::Type::kGauge,
                                   "Joint env steps in the queued unrolls."};
const metrics::Family kPushersWaiting{"imca_learner_pushers_waiting", metrics::Type::kGauge,
                                      "Pushes blocked on a full queue (back-pressure on the actors)."};
const metrics::Family kStalled{"imca_learner_stalled_seconds", metrics::Type::kGauge,
                               "Seconds the training thread has not taken queued unrolls while no update runs "
                               "(0 when idle or training): a learner that stays high is wedged."};
const metrics::Family kTraining{"imca_learner_training_seconds", metrics::Type::kGauge,
                                "Seconds the update running now has taken (0: none)."};
const metrics::Family kActorIds{"imca_learner_actor_ids", metrics::Type::kGauge,
                                "Distinct actor ids that have pushed unrolls."};
const metrics::Family kIncarnations{"imca_learner_actor_incarnations_total", metrics::Type::kCounter,
                                    "Actor incarnations seen: a restarted actor comes back as a new one."};
const metrics::Family kBudgetDone{"imca_learner_budget_done", metrics::Type::kGauge,
                                  "1 once the learner has trained its --steps, else 0."};
const metrics::Family kPolicyLag{"imca_learner_policy_lag_versions", metrics::Type::kHistogram,
                                 "Policy versions between an unroll's acting policy and the one it is trained "
                                 "into, per trained unroll.",
                                 {0, 1, 2, 3, 4, 6, 8, 12, 16, 32, 64}};

}  // namespace

Learner::Learner(const env::Scenario* scenario, const LearnerConfig& config, std::unique_ptr<Algorithm> algorithm)
    : scenario_(scenario),
      config_(config),
      algorithm_(std::move(algorithm)),
      queue_(UnrollQueue::Options{
          .capacity = config.queue_capacity,
          .synchronous = config.synchronous,
          .batch_steps = config.batch_steps,
          .max_policy_lag = algorithm_->off_policy() ? std::nullopt : std::optional<int>(config.max_policy_lag),
          .max_actor_ids = config.max_actor_ids,
          .validate = [this](const v1::Unroll& unroll) { return Validate(unroll); },
          .featurise = [this](v1::Unroll unroll) { return algorithm_->Featurise(std::move(unroll)); },
          // Deterministic: counted in batch order by Run instead.
          .on_accept = config.deterministic ? std::function<void(const v1::Unroll&)>()
                                            : [this](const v1::Unroll& unroll) { CountEpisodes(unroll); },
      }) {
  RegisterMetrics();
  if (!config_.run_dir.empty()) {
    checkpoints_.emplace((fs::path(config_.run_dir) / "checkpoints").string());
    metrics_log_.emplace((fs::path(config_.run_dir) / "metrics.csv").string(), CsvHeader(config_.algo, scenario_->num_agents()));
  }
  if (!config_.trained_log.empty()) {
    trained_log_.emplace(config_.trained_log, "iteration,actor_id,incarnation,sequence,policy_version");
  }
}

void Learner::RegisterMetrics() {
  dropped_ = registry_.AddCounterPerValue(kUnrollsDropped, "reason", RejectionReasons());
  policy_lag_ = &registry_.AddHistogram(kPolicyLag);
  // One lock of mu_ per scrape for all of them.
  registry_.AddSnapshot([this](metrics::Snapshot& s) {
    const UnrollQueue::Stats queue = queue_.stats();
    absl::MutexLock lock(&mu_);
    const auto now = std::chrono::steady_clock::now();
    s.Set(kUnrollsReceived, static_cast<double>(queue.received));
    s.Set(kBatchesDropped, static_cast<double>(batches_dropped_));
    s.Set(kMinibatchesSkipped, static_cast<double>(minibatches_skipped_));
    s.Set(kQueueDepth, static_cast<double>(queue.depth));
    s.Set(kQueuedSteps, static_cast<double>(queue.queued_steps));
    s.Set(kPushersWaiting, static_cast<double>(queue.pushers_waiting));
    s.Set(kActorIds, static_cast<double>(queue.actor_ids));
    s.Set(kIncarnations, static_cast<double>(queue.incarnations));
    s.Set(kBudgetDone, done_ ? 1.0 : 0.0);
    s.Set(kStalled, SecondsStalled(now, queue.depth));
    s.Set(kTraining, SecondsTraining(now));
  });
}

int64_t Learner::IterationBytes(int64_t steps) const { return algorithm_->IterationBytes(steps); }

absl::StatusOr<PushOutcome> Learner::Push(v1::Unroll unroll, const std::function<bool()>& cancelled) {
  absl::StatusOr<PushOutcome> outcome = queue_.Push(std::move(unroll), cancelled);
  if (outcome.ok() && !outcome->accepted()) dropped_[outcome->rejection]->Increment();
  return outcome;
}

void Learner::CountEpisodes(const v1::Unroll& u) {
  absl::MutexLock lock(&windows_mu_);
  for (float r : u.episode_returns()) PushWindow(&train_returns_, r, config_.metrics_window);
  for (bool s : u.episode_success()) PushWindow(&train_success_, s, config_.metrics_window);
  for (bool s : u.eval_success()) PushWindow(&eval_success_, s, config_.metrics_window);
}

PushOutcome Learner::Validate(const v1::Unroll& unroll) const {
  if (const absl::Status valid = ValidateUnroll(unroll, *scenario_, {true, true, algorithm_->needs_influences()});
      !valid.ok()) {
    return Refused(v1::REJECTION_INVALID, std::string(valid.message()));
  }
  // A batch gathers unrolls until it holds batch_steps, so the largest is
  // batch_steps - 1 steps plus this unroll.
  const int64_t steps = UnrollSteps(unroll);
  if (const int64_t bytes = IterationBytes(config_.batch_steps - 1 + steps); bytes > config_.max_batch_bytes) {
    return Refused(v1::REJECTION_OVER_CAP,
                   absl::StrFormat("unroll.length * unroll.num_envs = %d steps: a batch with it needs %.0f MB of "
                                   "features here, over the learner's cap of %.0f MB (use fewer envs or a shorter "
                                   "unroll)",
                                   steps, bytes / 1e6, config_.max_batch_bytes / 1e6));
  }
  return PushOutcome();
}

std::shared_ptr<const v1::Policy> Learner::CurrentPolicy() const {
  absl::MutexLock lock(&mu_);
  return policy_;
}

std::shared_ptr<const v1::Policy> Learner::WaitForPolicy(int64_t min_version, absl::Duration timeout) const {
  struct Wanted {
    const Learner* self;
    int64_t min_version;
  } wanted{this, min_version};
  absl::MutexLock lock(&mu_);
  mu_.AwaitWithTimeout(absl::Condition(
                           +[](Wanted* w) ABSL_EXCLUSIVE_LOCKS_REQUIRED(w->self->mu_) {
                             return w->self->stopping_ || w->self->version_ >= w->min_version;
                           },
                           &wanted),
                       timeout);
  return policy_;
}

v1::LearnerStatus Learner::Status() const {
  const UnrollQueue::Stats queue = queue_.stats();
  v1::LearnerStatus status;
  {
    absl::MutexLock lock(&windows_mu_);
    status.set_success_rate(Mean(eval_success_));
    status.set_episode_return(Mean(train_returns_));
  }
  absl::MutexLock lock(&mu_);
  const double wall =
      wall_offset_ + std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  status.set_policy_version(version_);
  status.set_env_steps(env_steps_);
  status.set_unrolls_received(queue.received);
  status.set_unrolls_dropped_stale(queue.stale);
  status.set_unrolls_rejected(queue.rejected);
  status.set_wall_seconds(wall);
  status.set_env_steps_per_sec(wall > 0 ? env_steps_ / wall : 0);
  status.set_intrinsic_reward(last_intrinsic_);
  status.set_done(done_);
  status.set_batches_dropped(batches_dropped_);
  status.set_queue_depth(queue.depth);
  status.set_pushers_waiting(queue.pushers_waiting);
  const auto now = std::chrono::steady_clock::now();
  status.set_seconds_stalled(SecondsStalled(now, queue.depth));
  status.set_seconds_training(SecondsTraining(now));
  status.set_unrolls_duplicate(queue.duplicate);
  status.set_actor_incarnations(queue.incarnations);
  status.set_minibatches_skipped(minibatches_skipped_);
  status.set_kernels(nn::KernelsInUse());
  for (const std::string& actor : queue_.ActorIds()) status.add_actors_seen(actor);
  return status;
}

double Learner::SecondsStalled(std::chrono::steady_clock::time_point now, int queue_depth) const {
  return queue_depth == 0 || training_since_.has_value()
             ? 0.0
             : std::chrono::duration<double>(now - last_progress_).count();
}

double Learner::SecondsTraining(std::chrono::steady_clock::time_point now) const {
  return training_since_.has_value() ? std::chrono::duration<double>(now - *training_since_).count() : 0.0;
}

void Learner::Stop() {
  absl::MutexLock lock(&mu_);
  stopping_ = true;
  queue_.Close(/*budget_done=*/false);
}

std::optional<FeaturisedUnroll> Learner::NextUnroll() {
  int dropped_stale = 0;
  std::optional<FeaturisedUnroll> next = queue_.Next(&dropped_stale);
  for (int i = 0; i < dropped_stale; ++i) dropped_[v1::REJECTION_STALE]->Increment();
  absl::MutexLock lock(&mu_);
  last_progress_ = std::chrono::steady_clock::now();
  return next;
}

absl::Status Learner::AddToBatch(FeaturisedUnroll* queued) {
  // Adding may train (MADDPG's due updates): like Train, it is not a stall.
  {
    absl::MutexLock lock(&mu_);
    training_since_ = std::chrono::steady_clock::now();
  }
  const absl::Status added = algorithm_->Add(*queued);
  absl::MutexLock lock(&mu_);
  training_since_.reset();
  last_progress_ = std::chrono::steady_clock::now();
  return added;
}

absl::Status Learner::Run() {
  while (true) {
    {
      absl::MutexLock lock(&mu_);
      if (stopping_ || (config_.budget_steps > 0 && env_steps_ >= config_.budget_steps)) break;
    }
    // Each unroll's values and advantages are computed as it arrives, while
    // the actors still produce the rest of the batch; a deterministic
    // learner holds them until the batch is whole and adds them in order.
    phases_ = Phases();
    std::vector<v1::Unroll> unrolls;
    std::vector<FeaturisedUnroll> held;  // Deterministic: the batch so far.
    int64_t steps = 0;
    Clock::time_point lap = Clock::now();
    while (steps < config_.batch_steps) {
      std::optional<FeaturisedUnroll> queued = NextUnroll();
      phases_.wait += Lap(lap);
      if (!queued.has_value()) break;  // Stopping.
      phases_.featurise += queued->featurise_seconds;
      steps += UnrollSteps(queued->unroll);
      if (config_.deterministic) {
        held.push_back(*std::move(queued));
      } else {
        IMCA_RETURN_IF_ERROR(AddToBatch(&*queued));
        unrolls.push_back(std::move(queued->unroll));
      }
      lap = Clock::now();
    }
    if (config_.deterministic && (steps >= config_.batch_steps || algorithm_->off_policy())) {
      std::sort(held.begin(), held.end(), [](const FeaturisedUnroll& a, const FeaturisedUnroll& b) {
        return std::make_tuple(std::cref(a.unroll.actor_id()), a.unroll.sequence(), a.unroll.incarnation()) <
               std::make_tuple(std::cref(b.unroll.actor_id()), b.unroll.sequence(), b.unroll.incarnation());
      });
      for (FeaturisedUnroll& queued : held) {
        CountEpisodes(queued.unroll);
        IMCA_RETURN_IF_ERROR(AddToBatch(&queued));
        unrolls.push_back(std::move(queued.unroll));
      }
    }
    if (steps < config_.batch_steps) {
      // Stopping mid-iteration: an off-policy algorithm has already trained
      // on what it added, so that iteration is counted and published (the
      // final checkpoint's weights then match its version); MAPPO's partial
      // batch is dropped untrained.
      if (algorithm_->off_policy() && !unrolls.empty()) IMCA_RETURN_IF_ERROR(TrainOn(unrolls));
      break;
    }
    IMCA_RETURN_IF_ERROR(TrainOn(unrolls));
    if ((config_.checkpoint_every > 0 && iteration_ % config_.checkpoint_every == 0) ||
        (config_.checkpoint_seconds > 0 &&
         Clock::now() - last_checkpoint_ >= std::chrono::duration<double>(config_.checkpoint_seconds))) {
      IMCA_RETURN_IF_ERROR(SaveCheckpoint());
    }
  }
  {
    absl::MutexLock lock(&mu_);
    done_ = config_.budget_steps > 0 && env_steps_ >= config_.budget_steps;
    stopping_ = true;
    queue_.Close(done_);
  }
  return SaveCheckpoint();
}

absl::Status Learner::TrainOn(const std::vector<v1::Unroll>& unrolls) {
  {
    absl::MutexLock lock(&mu_);
    training_since_ = std::chrono::steady_clock::now();
  }
  absl::StatusOr<IterationStats> trained = algorithm_->Train();
  {
    absl::MutexLock lock(&mu_);
    training_since_.reset();
    last_progress_ = std::chrono::steady_clock::now();
  }
  IterationStats stats;
  bool refused = false;  // The algorithm refused the batch: nothing of it was trained.
  if (trained.ok()) {
    stats = *std::move(trained);
    if (stats.minibatches_skipped > 0) {
      std::fprintf(stderr, "learner: iteration %lld: %lld minibatches took no step (%s)\n",
                   static_cast<long long>(iteration_ + 1), static_cast<long long>(stats.minibatches_skipped),
                   stats.skip_reason.c_str());
    }
  } else if (absl::IsInvalidArgument(trained.status())) {
    // A batch the trainer refuses (e.g. an advantage that overflowed from
    // validated but extreme unrolls) never ends training: it is dropped and
    // counted, and the same weights are published as the next version so
    // that synchronous actors move on.
    std::fprintf(stderr, "learner: iteration %lld: %s\n", static_cast<long long>(iteration_ + 1),
                 std::string(trained.status().message()).c_str());
    refused = true;
    absl::MutexLock lock(&mu_);
    ++batches_dropped_;
  } else {
    return trained.status();
  }
  ++iteration_;
  int64_t steps = 0;
  double lag = 0;
  int64_t version;
  {
    absl::MutexLock lock(&mu_);
    version = version_;
  }
  for (const v1::Unroll& u : unrolls) {
    steps += UnrollSteps(u);
    lag += static_cast<double>(version - u.policy_version()) / unrolls.size();
    if (!refused) policy_lag_->Observe(static_cast<double>(version - u.policy_version()));
  }
  const CreditStats credit = MeasureCredit(unrolls, steps * scenario_->num_agents());
  queue_.MarkTrained(unrolls);
  {
    absl::MutexLock lock(&mu_);
    env_steps_ += steps;
    minibatches_skipped_ += stats.minibatches_skipped;
    last_intrinsic_ = credit.intrinsic;
  }
  if (trained_log_.has_value()) {
    // One row per trained unroll: what a resend or a restart could make
    // train twice, for a reader to check that it did not.
    for (const v1::Unroll& u : unrolls) {
      AppendRow(&*trained_log_, absl::StrFormat("%d,%s,%016x,%d,%d", iteration_, u.actor_id(), u.incarnation(),
                                                u.sequence(), u.policy_version()));
    }
  }
  Clock::time_point lap = Clock::now();
  Publish();
  phases_.publish = Lap(lap);
  const IterationRecord record = Record(stats, lag, credit);
  exporter_.Publish(record);
  if (metrics_log_.has_value()) AppendRow(&*metrics_log_, CsvRow(config_.algo, record));
  return absl::OkStatus();
}

Learner::CreditStats Learner::MeasureCredit(const std::vector<v1::Unroll>& unrolls, int64_t agent_steps) const {
  const int n = scenario_->num_agents();
  CreditStats c;
  c.shares.assign(n, 0.0);
  int64_t shared_rows = 0, global_rows = 0, contribution_values = 0;
  for (const v1::Unroll& u : unrolls) {
    for (float r : u.intrinsic_rewards()) c.intrinsic += r;
    for (int64_t i = 0; i + n <= u.credit_shares_size(); i += n) {
      const float* row = u.credit_shares().data() + i;
      c.share_max += *std::max_element(row, row + n);
      for (int a = 0; a < n; ++a) c.shares[a] += row[a];
      ++shared_rows;
    }
    for (float r : u.global_rewards()) c.global_reward += r;
    global_rows += u.global_rewards_size();
    for (float r : u.contributions()) c.contribution_abs += std::abs(r);
    contribution_values += u.contributions_size();
  }
  if (agent_steps > 0) c.intrinsic /= static_cast<double>(agent_steps);
  if (shared_rows > 0) {
    c.share_max /= shared_rows;
    for (double& p : c.shares) p /= shared_rows;
  }
  if (global_rows > 0) c.global_reward /= global_rows;
  if (contribution_values > 0) c.contribution_abs /= contribution_values;
  return c;
}

void Learner::Publish() {
  absl::MutexLock lock(&mu_);
  last_progress_ = std::chrono::steady_clock::now();
  if (policy_ != nullptr) ++version_;
  policy_ = ExportPolicy();
  // Under mu_: no actor sees the new policy before the queue judges unrolls by it.
  queue_.NewVersion(version_);
}

std::shared_ptr<const v1::Policy> Learner::ExportPolicy() const {
  v1::Policy policy = algorithm_->ExportPolicy(version_);
  policy.set_sync_steps_per_actor(config_.synchronous ? config_.batch_steps / config_.actors : 0);
  policy.set_final(config_.budget_steps > 0 && env_steps_ >= config_.budget_steps);
  return std::make_shared<const v1::Policy>(std::move(policy));
}

IterationRecord Learner::Record(const IterationStats& stats, double lag, const CreditStats& credit) const {
  const v1::LearnerStatus s = Status();
  IterationRecord r;
  {
    absl::MutexLock lock(&windows_mu_);
    r.train_success_rate = Mean(train_success_);
    r.success_episodes = static_cast<double>(eval_success_.size());
    r.train_success_episodes = static_cast<double>(train_success_.size());
  }
  r.iteration = static_cast<double>(iteration_);
  r.env_steps = static_cast<double>(s.env_steps());
  r.wall_seconds = s.wall_seconds();
  r.env_steps_per_sec = s.env_steps_per_sec();
  r.success_rate = s.success_rate();
  r.episode_return = s.episode_return();
  r.intrinsic_reward = credit.intrinsic;
  r.share_max = credit.share_max;
  r.policy_version = static_cast<double>(s.policy_version());
  r.policy_lag = lag;
  r.dropped_stale = static_cast<double>(s.unrolls_dropped_stale());
  r.entropy = stats.entropy;
  r.wait = phases_.wait;
  r.featurise = phases_.featurise;
  r.values = stats.seconds_values;
  r.gae = stats.seconds_gae;
  r.copy = stats.seconds_copy;
  r.prepare = stats.seconds_prepare;
  r.forward = stats.seconds_forward;
  r.backward = stats.seconds_backward;
  r.optimizer = stats.seconds_optimizer;
  r.publish = phases_.publish;
  r.global_reward = credit.global_reward;
  r.contribution_abs = credit.contribution_abs;
  r.updates = static_cast<double>(stats.updates);
  r.algorithm.insert(stats.values.begin(), stats.values.end());
  r.shares = credit.shares;
  return r;
}

void Learner::AppendRow(CsvLog* log, absl::string_view row) {
  const bool was_healthy = log->healthy();
  const absl::Status written = log->Append(row);
  if (!written.ok() && was_healthy) std::fprintf(stderr, "learner: %s\n", std::string(written.message()).c_str());
}

absl::Status Learner::SaveCheckpoint() {
  last_checkpoint_ = Clock::now();
  if (!checkpoints_.has_value()) return absl::OkStatus();
  const v1::LearnerStatus s = Status();
  v1::CheckpointMeta meta;
  meta.set_version(s.policy_version());
  meta.set_env_steps(s.env_steps());
  meta.set_wall_seconds(s.wall_seconds());
  meta.set_iteration(iteration_);
  // The newest trained unroll of each actor incarnation, so that a
  // restarted learner still recognises resends of what it trained (and
  // takes again what was only queued: that was lost with the process).
  // By actor id, so that equal runs write equal metadata (but for the wall
  // clock and the incarnations, which are each process's own).
  const absl::flat_hash_map<std::string, UnrollQueue::Accepted> by_actor = queue_.Trained();
  const std::map<std::string, UnrollQueue::Accepted> sorted(by_actor.begin(), by_actor.end());
  for (const auto& [actor, accepted] : sorted) {
    v1::CheckpointMeta::Trained* trained = meta.add_trained();
    trained->set_actor_id(actor);
    trained->set_incarnation(accepted.incarnation);
    trained->set_sequence(accepted.sequence);
  }
  IMCA_RETURN_IF_ERROR(checkpoints_->Save(meta, [this](const std::string& path) { return algorithm_->Save(path); }));
  // The newest policy as a serialized imca.v1.Policy, for tools in any language.
  return WriteFileAtomically((fs::path(config_.run_dir) / "policy.pb").string(), CurrentPolicy()->SerializeAsString());
}

absl::Status Learner::Restore(const std::string& checkpoint_dir) {
  IMCA_ASSIGN_OR_RETURN(const v1::CheckpointMeta meta,
                        CheckpointStore(checkpoint_dir).Restore([this](const std::string& path) {
                          return algorithm_->Load(path);
                        }));
  absl::flat_hash_map<std::string, UnrollQueue::Accepted> trained;
  for (const v1::CheckpointMeta::Trained& t : meta.trained()) {
    trained[t.actor_id()] = UnrollQueue::Accepted{t.incarnation(), t.sequence()};
  }
  iteration_ = meta.iteration();
  {
    absl::MutexLock lock(&mu_);
    wall_offset_ = meta.wall_seconds();
    version_ = meta.version();
    env_steps_ = meta.env_steps();
    queue_.Restore(version_, trained);
    policy_ = ExportPolicy();
  }
  // The cumulative families start from the checkpoint, not from 0 (a
  // counter's jump from 0 would read as a burst of training).
  IterationRecord record;
  record.iteration = static_cast<double>(iteration_);
  record.env_steps = static_cast<double>(meta.env_steps());
  record.policy_version = static_cast<double>(meta.version());
  exporter_.Publish(record);
  return absl::OkStatus();
}

}  // namespace imca::learner
