#include "learner/algorithms/mappo/ppo_trainer.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <functional>
#include <limits>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <ATen/CPUGeneratorImpl.h>
#include <torch/torch.h>

#include "absl/base/thread_annotations.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/synchronization/mutex.h"
#include "common/base/atomic_file.h"
#include "common/base/checks.h"
#include "common/base/enum_names.h"
#include "common/base/lap.h"
#include "common/base/side_thread.h"
#include "common/base/status_macros.h"
#include "common/nn/archive.h"
#include "common/nn/mlp.h"
#include "common/nn/policy_export.h"
#include "common/nn/running_moments.h"
#include "common/nn/torch_status.h"
#include "learner/algorithms/mappo/ppo_losses.h"

namespace imca::learner {

namespace {

using internal::BehaviourKl;
using internal::CopyFloats;
using internal::NormaliseAdvantages;
using internal::ReturnNormaliser;

// A recorded log-probability may round slightly above 0 when p ~ 1.
constexpr float kMaxLogProb = 1e-4f;


// Everything the optimisers are bound to. Load builds a fresh one and swaps
// it in only when the whole checkpoint has been read, so a failed load
// changes nothing.
struct Model {
  nn::Mlp actor{nullptr};
  nn::Mlp critic{nullptr};
  // One group per optimiser: {actor's and critic's} with one optimiser, or
  // {actor's}, {critic's} with separate ones. Each group's gradient norm is
  // clipped on its own.
  std::vector<std::vector<torch::Tensor>> groups;
  std::vector<std::unique_ptr<torch::optim::Adam>> optimizers;

  void ZeroGrad() {
    for (auto& optimizer : optimizers) optimizer->zero_grad();
  }
};

Model BuildModel(const PpoConfig& config, int obs_dim, int critic_dim, int num_actions) {
  Model model;
  // Three Linear layers, tanh after the first two, orthogonal weights
  // (last layer gain 0.01 for the actor, 1 for the critic), zero biases: the
  // usual PPO initialisation; actor and critic from streams 1 and 2 of the seed.
  const auto mlp = [&](int64_t in, int64_t out, double last_gain, uint64_t stream) {
    return nn::Mlp(nn::MlpOptions({in, config.hidden, config.hidden, out})
                       .activation(nn::Activation::kTanh)
                       .hidden_gain(config.hidden_gain)
                       .last_gain(last_gain)
                       .layer_norm(config.layer_norm)
                       .input_norm(config.input_norm)
                       .seed(nn::SubSeed(config.seed, stream)));
  };
  model.actor = mlp(obs_dim, num_actions, /*last_gain=*/0.01, 1);
  // Outputs: normalised extrinsic (and intrinsic) values.
  model.critic = mlp(critic_dim, config.value_heads, /*last_gain=*/1.0, 2);
  std::vector<torch::Tensor> actor = model.actor->parameters();
  std::vector<torch::Tensor> critic = model.critic->parameters();
  if (config.separate_optimizers) {
    model.groups = {std::move(actor), std::move(critic)};
  } else {
    actor.insert(actor.end(), critic.begin(), critic.end());
    model.groups = {std::move(actor)};
  }
  for (const auto& group : model.groups) {
    model.optimizers.push_back(std::make_unique<torch::optim::Adam>(
        group, torch::optim::AdamOptions(config.learning_rate).eps(config.adam_eps)));
  }
  return model;
}


// The batch as tensors, advantages and value targets already normalised.
struct TrainData {
  torch::Tensor obs;                  // [B, obs_dim]
  torch::Tensor critic_inputs;        // [B, critic_dim]
  torch::Tensor actions;              // [B] int64
  torch::Tensor behaviour_log_probs;  // [B]
  // [B], the actor's before this iteration's updates (kDecoupled only).
  torch::Tensor start_log_probs;
  torch::Tensor advantages;           // [B]
  // [B, value_heads]: normalised with ValueNorm::kBatch; with kEma the raw
  // returns, normalised per minibatch as its normaliser update goes.
  torch::Tensor value_targets;
  torch::Tensor start_values;         // [B, value_heads], normalised; only with value_clip.
};

// Sums over minibatch updates, turned into averages by Finish():
// losses, entropy and grad norm are means over updates; approx_kl is the
// mean over the samples of the last epoch; clip_fraction is the share of
// clipped samples over all epochs.
struct StatsSums {
  double policy_loss = 0;
  double value_loss = 0;
  double entropy = 0;
  double grad_norm = 0;
  int64_t updates = 0;
  double behaviour_kl = 0;
  double seconds_prepare = 0;
  double seconds_forward = 0;
  double seconds_backward = 0;
  double seconds_optimizer = 0;
  double kl = 0;
  int64_t kl_samples = 0;
  int64_t clipped = 0;
  int64_t samples = 0;
  int64_t skipped = 0;
  std::string skip_reason;  // The first skipped minibatch's.

  void Skip(std::string reason) {
    if (skipped++ == 0) skip_reason = std::move(reason);
  }

  PpoStats Finish() const {
    PpoStats s;
    s.minibatches_skipped = skipped;
    s.skip_reason = skip_reason;
    const double u = std::max<int64_t>(updates, 1);
    s.policy_loss = policy_loss / u;
    s.value_loss = value_loss / u;
    s.entropy = entropy / u;
    s.grad_norm = grad_norm / u;
    s.approx_kl = kl / std::max<int64_t>(kl_samples, 1);
    s.clip_fraction = static_cast<double>(clipped) / std::max<int64_t>(samples, 1);
    s.behaviour_kl = behaviour_kl;
    s.seconds_prepare = seconds_prepare;
    s.seconds_forward = seconds_forward;
    s.seconds_backward = seconds_backward;
    s.seconds_optimizer = seconds_optimizer;
    return s;
  }
};

// Parameters of `loaded` must have the shapes of `expected` (Module::load
// adopts whatever shape the file holds).
absl::Status CheckSameShapes(const torch::nn::Module& expected, const torch::nn::Module& loaded,
                             const std::string& what) {
  const auto want = expected.named_parameters();
  const auto got = loaded.named_parameters();
  for (const auto& item : want) {
    const torch::Tensor* t = got.find(item.key());
    if (t == nullptr || t->sizes() != item.value().sizes()) {
      return absl::InvalidArgumentError(
          absl::StrCat("checkpoint ", what, ".", item.key(), " has shape ",
                       t == nullptr ? "(missing)" : c10::str(t->sizes()), ", expected ",
                       c10::str(item.value().sizes())));
    }
  }
  return absl::OkStatus();
}

// [layer norms, value_heads, number of optimisers, value normaliser]: what
// a checkpoint must agree on beyond the sizes in "dims". Layer norms: 0
// none, 1 on the input and after the hidden layers, 2 after the hidden
// layers only; value normaliser: 0 kBatch, 1 kEma.
std::vector<int64_t> Architecture(const PpoConfig& config) {
  const int64_t norms = !config.layer_norm ? 0 : config.input_norm ? 1 : 2;
  return {norms, int64_t{config.value_heads}, config.separate_optimizers ? 2 : 1,
          config.value_norm == ValueNorm::kEma ? 1 : 0};
}

// The checkpoint names of the value heads' normalisers (extrinsic,
// intrinsic, interaction), in head order. The first two are always written.
constexpr const char* kNormaliserNames[] = {"value_norm_ext", "value_norm_int", "value_norm_voi"};
constexpr int kMaxValueHeads = 3;

// The elements of an integer tensor of any shape.
std::vector<int64_t> Int64s(const torch::Tensor& t) {
  const torch::Tensor c = t.to(torch::kInt64).flatten().contiguous();
  return std::vector<int64_t>(c.data_ptr<int64_t>(), c.data_ptr<int64_t>() + c.numel());
}

}  // namespace

struct PpoTrainer::Impl {
  Impl(const PpoConfig& config, int obs_dim, int critic_dim, int num_actions)
      : config_(config),
        obs_dim_(obs_dim),
        critic_dim_(critic_dim),
        num_actions_(num_actions),
        norms_{ReturnNormaliser(config.value_norm), ReturnNormaliser(config.value_norm),
               ReturnNormaliser(config.value_norm)},
        generator_(at::detail::createCPUGenerator(config.seed)) {
    model_ = BuildModel(config_, obs_dim_, critic_dim_, num_actions_);
    if (config.concurrent_critic) {
      // OpenMP's thread count is per thread: without this the side thread's
      // ops would use every core.
      critic_thread_ = std::make_unique<SideThread>([threads = config.threads] { torch::set_num_threads(threads); });
    }
  }

  absl::Status ValidateBatch(const PpoBatch& batch) const;
  TrainData MakeTrainData(const PpoBatch& batch);
  absl::StatusOr<PpoStats> Train(const PpoBatch& batch);
  absl::Status TrainMinibatch(const TrainData& data, const torch::Tensor& indices, bool last_epoch,
                              StatsSums& sums);
  void WriteTo(torch::serialize::OutputArchive& archive) const;
  absl::Status ReadFrom(torch::serialize::InputArchive& archive, const std::string& path);

  const PpoConfig config_;
  const int obs_dim_;
  const int critic_dim_;
  const int num_actions_;
  Model model_;
  // Normalised returns [rows, value_heads] from raw ones, each head's
  // normaliser taking its column first: a whole batch once per iteration
  // (ValueNorm::kBatch) or each minibatch of every epoch (kEma, as on-policy).
  torch::Tensor TakeAndNormalise(const torch::Tensor& returns);
  // The checkpoint tensors this trainer writes and reads: the extrinsic and
  // intrinsic heads' always, the interaction head's with three heads.
  int StoredNormalisers() const { return std::max(2, config_.value_heads); }

  // One per value head, in head order (kNormaliserNames); the unused ones
  // stay as they started.
  std::array<ReturnNormaliser, kMaxValueHeads> norms_;
  at::Generator generator_;  // Minibatch shuffling only; saved in checkpoints.
  std::unique_ptr<SideThread> critic_thread_;  // With config.concurrent_critic.
};

absl::Status PpoTrainer::Impl::ValidateBatch(const PpoBatch& batch) const {
  const int64_t b = batch.size;
  if (b <= 0) {
    return absl::InvalidArgumentError(absl::StrCat("batch.size is ", b, ", expected > 0"));
  }
  if (b > std::numeric_limits<int64_t>::max() / std::max(obs_dim_, critic_dim_)) {
    return absl::InvalidArgumentError(absl::StrCat("batch.size ", b, " is too large"));
  }
  IMCA_RETURN_IF_ERROR(CheckSize("batch", "obs", batch.obs, b * obs_dim_));
  IMCA_RETURN_IF_ERROR(CheckSize("batch", "critic_inputs", batch.critic_inputs, b * critic_dim_));
  IMCA_RETURN_IF_ERROR(CheckSize("batch", "actions", batch.actions, b));
  IMCA_RETURN_IF_ERROR(CheckSize("batch", "behaviour_log_probs", batch.behaviour_log_probs, b));
  IMCA_RETURN_IF_ERROR(CheckSize("batch", "advantages", batch.advantages, b));
  IMCA_RETURN_IF_ERROR(CheckSize("batch", "returns_ext", batch.returns_ext, b));
  IMCA_RETURN_IF_ERROR(CheckSize("batch", "returns_int", batch.returns_int, b));
  if (config_.value_heads == 3) IMCA_RETURN_IF_ERROR(CheckSize("batch", "returns_voi", batch.returns_voi, b));
  for (int64_t i = 0; i < b; ++i) {
    const int32_t a = batch.actions[i];
    if (a < 0 || a >= num_actions_) {
      return absl::InvalidArgumentError(
          absl::StrCat("batch.actions[", i, "] = ", a, " is out of range [0, ", num_actions_, ")"));
    }
  }
  IMCA_RETURN_IF_ERROR(CheckFinite("batch", "obs", batch.obs));
  IMCA_RETURN_IF_ERROR(CheckFinite("batch", "critic_inputs", batch.critic_inputs));
  IMCA_RETURN_IF_ERROR(CheckFinite("batch", "behaviour_log_probs", batch.behaviour_log_probs));
  IMCA_RETURN_IF_ERROR(CheckFinite("batch", "advantages", batch.advantages));
  IMCA_RETURN_IF_ERROR(CheckFinite("batch", "returns_ext", batch.returns_ext));
  IMCA_RETURN_IF_ERROR(CheckFinite("batch", "returns_int", batch.returns_int));
  if (config_.value_heads == 3) IMCA_RETURN_IF_ERROR(CheckFinite("batch", "returns_voi", batch.returns_voi));
  for (int64_t i = 0; i < b; ++i) {
    if (batch.behaviour_log_probs[i] > kMaxLogProb) {
      return absl::InvalidArgumentError(absl::StrCat("batch.behaviour_log_probs[", i,
                                                     "] = ", batch.behaviour_log_probs[i],
                                                     " is not a log-probability (> 0)"));
    }
  }
  return absl::OkStatus();
}

TrainData PpoTrainer::Impl::MakeTrainData(const PpoBatch& batch) {
  const int64_t b = batch.size;
  TrainData data;
  // Views, not copies: `batch` outlives Train and is not modified meanwhile,
  // and every minibatch gathers its rows anyway.
  data.obs = torch::from_blob(const_cast<float*>(batch.obs.data()), {b, obs_dim_}, torch::kFloat32);
  data.critic_inputs =
      torch::from_blob(const_cast<float*>(batch.critic_inputs.data()), {b, critic_dim_}, torch::kFloat32);
  data.actions = torch::from_blob(const_cast<int32_t*>(batch.actions.data()), {b}, torch::kInt32)
                     .to(torch::kInt64);
  data.behaviour_log_probs = CopyFloats(batch.behaviour_log_probs, {b});
  data.advantages = NormaliseAdvantages(CopyFloats(batch.advantages, {b}));
  // One column per value head: extrinsic, intrinsic, interaction.
  const std::vector<float>* returns[] = {&batch.returns_ext, &batch.returns_int, &batch.returns_voi};
  std::vector<torch::Tensor> columns;
  for (int h = 0; h < config_.value_heads; ++h) {
    columns.push_back(torch::from_blob(const_cast<float*>(returns[h]->data()), {b}, torch::kFloat32));
  }
  data.value_targets = torch::stack(columns, /*dim=*/1);  // A copy.
  if (config_.value_norm == ValueNorm::kBatch) data.value_targets = TakeAndNormalise(data.value_targets);
  // The networks as they are before this iteration's first update: the
  // proximal policy of the decoupled objective, and the anchor of value
  // clipping.
  torch::NoGradGuard no_grad;
  if (config_.objective == PpoObjective::kDecoupled) {
    data.start_log_probs = torch::log_softmax(model_.actor->forward(data.obs), /*dim=*/1)
                               .gather(1, data.actions.unsqueeze(1))
                               .squeeze(1);
  }
  if (config_.value_clip > 0) data.start_values = model_.critic->forward(data.critic_inputs);
  return data;
}

torch::Tensor PpoTrainer::Impl::TakeAndNormalise(const torch::Tensor& returns) {
  std::vector<torch::Tensor> columns;
  for (int64_t h = 0; h < returns.size(1); ++h) {
    const torch::Tensor column = returns.select(1, h);
    norms_[h].Update(column);
    columns.push_back(norms_[h].Normalise(column));
  }
  return torch::stack(columns, /*dim=*/1);
}

absl::StatusOr<PpoStats> PpoTrainer::Impl::Train(const PpoBatch& batch) {
  Clock::time_point lap = Clock::now();
  const TrainData data = MakeTrainData(batch);
  const int64_t b = batch.size;
  // With fewer samples than minibatches, every minibatch holds one sample.
  const int64_t minibatches = std::min<int64_t>(config_.minibatches, b);
  StatsSums sums;
  if (data.start_log_probs.defined()) {
    sums.behaviour_kl = BehaviourKl(data.start_log_probs, data.behaviour_log_probs);
  }
  sums.seconds_prepare = Lap(lap);
  for (int epoch = 0; epoch < config_.epochs; ++epoch) {
    const torch::Tensor order = torch::randperm(b, generator_, torch::kInt64);
    for (int64_t k = 0; k < minibatches; ++k) {
      const int64_t begin = k * b / minibatches;
      const int64_t end = (k + 1) * b / minibatches;
      IMCA_RETURN_IF_ERROR(
          TrainMinibatch(data, order.slice(0, begin, end), epoch == config_.epochs - 1, sums));
    }
  }
  return sums.Finish();
}

absl::Status PpoTrainer::Impl::TrainMinibatch(const TrainData& data, const torch::Tensor& indices,
                                              bool last_epoch, StatsSums& sums) {
  Clock::time_point lap = Clock::now();
  const torch::Tensor actions = data.actions.index_select(0, indices);
  const torch::Tensor behaviour = data.behaviour_log_probs.index_select(0, indices);
  const torch::Tensor advantages = data.advantages.index_select(0, indices);
  // The policy the clip is measured against: the proximal one (decoupled),
  // else the behaviour policy itself (importance weight 1).
  const torch::Tensor anchor = config_.objective == PpoObjective::kDecoupled
                                   ? data.start_log_probs.index_select(0, indices)
                                   : behaviour;

  // Actor and critic share no parameters, so each backward pass of its own
  // loss gives its parameters exactly the gradient of the summed loss
  // (policy + value_coef * value - entropy_coef * entropy), and the two can
  // run at once.
  model_.ZeroGrad();
  torch::Tensor value_loss;
  const auto critic_forward = [&] {
    const torch::Tensor values = model_.critic->forward(data.critic_inputs.index_select(0, indices));
    torch::Tensor targets = data.value_targets.index_select(0, indices);
    if (config_.value_norm == ValueNorm::kEma) targets = TakeAndNormalise(targets);
    const auto error_loss = [&](const torch::Tensor& predictions) {
      return config_.huber_delta > 0
                 ? torch::huber_loss(predictions, targets, at::Reduction::None, config_.huber_delta)
                 : torch::mse_loss(predictions, targets, at::Reduction::None);
    };
    torch::Tensor per_sample = error_loss(values);
    if (config_.value_clip > 0) {
      const torch::Tensor start = data.start_values.index_select(0, indices);
      per_sample = torch::max(per_sample, error_loss(start + torch::clamp(values - start, -config_.value_clip,
                                                                          config_.value_clip)));
    }
    value_loss = per_sample.mean(/*dim=*/0).sum();  // Mean per head, summed over the heads.
  };
  const auto critic_backward = [&] { (config_.value_coef * value_loss).backward(); };
  struct WaitOnExit {  // If the actor's passes throw, the task's locals must outlive it.
    SideThread* thread;
    ~WaitOnExit() {
      if (thread != nullptr) thread->Wait();
    }
  } wait_on_exit{critic_thread_.get()};
  if (critic_thread_ != nullptr) {
    critic_thread_->Start([&] {
      critic_forward();
      critic_backward();
    });
  }

  const torch::Tensor log_probs_all =
      torch::log_softmax(model_.actor->forward(data.obs.index_select(0, indices)), /*dim=*/1);
  const torch::Tensor log_probs = log_probs_all.gather(1, actions.unsqueeze(1)).squeeze(1);
  const torch::Tensor entropy = -(log_probs_all.exp() * log_probs_all).sum(1).mean();
  const torch::Tensor policy_loss =
      internal::DecoupledSurrogateLoss(log_probs, anchor, behaviour, advantages, config_.clip);
  if (critic_thread_ == nullptr) critic_forward();
  // With the concurrent critic: the actor's passes on this thread, and the
  // wait for the critic counts as backward.
  sums.seconds_forward += Lap(lap);
  (policy_loss - config_.entropy_coef * entropy).backward();
  if (critic_thread_ != nullptr) {
    critic_thread_->Join();
  } else {
    critic_backward();
  }
  sums.seconds_backward += Lap(lap);

  const double policy_value = policy_loss.item<double>();
  const double value_value = value_loss.item<double>();
  const double entropy_value = entropy.item<double>();
  const double loss_value =
      policy_value + config_.value_coef * value_value - config_.entropy_coef * entropy_value;
  // A minibatch whose loss or gradient is not finite takes no step; it is
  // counted, and the iteration goes on with the next one.
  if (!std::isfinite(loss_value)) {
    model_.ZeroGrad();
    sums.Skip(absl::StrCat("non-finite PPO loss ", loss_value, " (policy ", policy_value, ", value ",
                           value_value, ", entropy ", entropy_value, ")"));
    return absl::OkStatus();
  }
  double grad_norm_sq = 0;  // Of all parameters together, whatever the grouping.
  for (const auto& group : model_.groups) {
    // Measured before clipping, so that no parameter is scaled by a
    // non-finite factor.
    double norm_sq = 0;
    for (const torch::Tensor& p : group) {
      if (p.grad().defined()) norm_sq += p.grad().to(torch::kFloat64).pow(2).sum().item<double>();
    }
    if (!std::isfinite(norm_sq)) {
      model_.ZeroGrad();
      sums.Skip(absl::StrCat("non-finite gradient norm ", std::sqrt(norm_sq)));
      return absl::OkStatus();
    }
  }
  for (const auto& group : model_.groups) {
    const double norm = torch::nn::utils::clip_grad_norm_(group, config_.max_grad_norm);
    grad_norm_sq += norm * norm;
  }
  const double grad_norm = std::sqrt(grad_norm_sq);
  for (auto& optimizer : model_.optimizers) optimizer->step();
  sums.seconds_optimizer += Lap(lap);

  // Diagnostics, from the forward pass before this step.
  torch::NoGradGuard no_grad;
  if (sums.updates == 0 && !data.start_log_probs.defined()) {
    // Without a proximal pass, the first minibatch's forward pass is the
    // only one at the start policy: staleness is measured on it.
    sums.behaviour_kl = BehaviourKl(log_probs.detach(), behaviour);
  }
  const torch::Tensor log_ratio = log_probs.detach() - anchor;
  const torch::Tensor ratio = log_ratio.exp();
  sums.policy_loss += policy_value;
  sums.value_loss += value_value;
  sums.entropy += entropy_value;
  sums.grad_norm += grad_norm;
  ++sums.updates;
  sums.clipped += ((ratio - 1.0).abs() > config_.clip).sum().item<int64_t>();
  sums.samples += indices.numel();
  if (last_epoch) {
    // In float64: (r - 1) - log r >= 0, but float32 rounds it below 0 near r = 1.
    const torch::Tensor log_ratio64 = log_ratio.to(torch::kFloat64);
    sums.kl += (torch::expm1(log_ratio64) - log_ratio64).sum().item<double>();
    sums.kl_samples += indices.numel();
  }
  return absl::OkStatus();
}

// Checkpoint layout: "dims" (int64 [obs_dim, critic_dim, num_actions,
// hidden]), "architecture" (int64, Architecture(); absent in checkpoints
// from before these options: [0, 2, 1], and without its fourth element from
// before value_norm: 0), sub-archives "actor", "critic", "optimizer" (and
// "optimizer_critic" with separate optimisers), the normalisers' float64 [3]
// tensors (ReturnNormaliser::ToTensor) "value_norm_ext"/"value_norm_int"
// (and "value_norm_voi" with three heads), and "generator" (the shuffling
// RNG state).
void PpoTrainer::Impl::WriteTo(torch::serialize::OutputArchive& archive) const {
  archive.write(
      "dims",
      torch::tensor({static_cast<int64_t>(obs_dim_), static_cast<int64_t>(critic_dim_),
                     static_cast<int64_t>(num_actions_), static_cast<int64_t>(config_.hidden)},
                    torch::kInt64));
  torch::serialize::OutputArchive actor(archive.compilation_unit());
  model_.actor->save(actor);
  archive.write("actor", actor);
  torch::serialize::OutputArchive critic(archive.compilation_unit());
  model_.critic->save(critic);
  archive.write("critic", critic);
  archive.write("architecture", torch::tensor(Architecture(config_), torch::kInt64));
  for (size_t i = 0; i < model_.optimizers.size(); ++i) {
    nn::WriteAdam(archive, i == 0 ? "optimizer" : "optimizer_critic", *model_.optimizers[i]);
  }
  for (int h = 0; h < StoredNormalisers(); ++h) archive.write(kNormaliserNames[h], norms_[h].ToTensor());
  archive.write("generator", generator_.get_state());
}

// Reads into fresh objects and commits only when everything checked out.
// The optimiser's hyperparameters (lr, eps) stay those of this trainer's
// config; only its state (moments, step counts) comes from the file.
absl::Status PpoTrainer::Impl::ReadFrom(torch::serialize::InputArchive& archive,
                                        const std::string& path) {
  torch::Tensor dims;
  archive.read("dims", dims);
  const std::vector<int64_t> want = {obs_dim_, critic_dim_, num_actions_, config_.hidden};
  const std::vector<int64_t> have = Int64s(dims);
  if (have != want) {
    return absl::InvalidArgumentError(absl::StrCat(
        "checkpoint ", path, " has (obs_dim, critic_dim, num_actions, hidden) = (",
        absl::StrJoin(have, ", "), "), this trainer has (", absl::StrJoin(want, ", "), ")"));
  }
  torch::Tensor architecture;
  // Checkpoints from before these options hold the original architecture.
  std::vector<int64_t> arch_have = archive.try_read("architecture", architecture)
                                       ? Int64s(architecture)
                                       : std::vector<int64_t>{0, 2, 1};
  if (arch_have.size() == 3) arch_have.push_back(0);
  const std::vector<int64_t> arch_want = Architecture(config_);
  if (arch_have != arch_want) {
    return absl::InvalidArgumentError(absl::StrCat(
        "checkpoint ", path, " has (layer norms, value_heads, optimizers, value_norm) = (",
        absl::StrJoin(arch_have, ", "), "), this trainer has (", absl::StrJoin(arch_want, ", "),
        "); start the learner with the checkpoint's --layer_norm and --input_norm, --value_heads, "
        "--separate_optimizers and --value_norm"));
  }
  Model fresh = BuildModel(config_, obs_dim_, critic_dim_, num_actions_);
  torch::serialize::InputArchive actor;
  archive.read("actor", actor);
  fresh.actor->load(actor);
  IMCA_RETURN_IF_ERROR(CheckSameShapes(*model_.actor, *fresh.actor, "actor"));
  torch::serialize::InputArchive critic;
  archive.read("critic", critic);
  fresh.critic->load(critic);
  IMCA_RETURN_IF_ERROR(CheckSameShapes(*model_.critic, *fresh.critic, "critic"));
  for (size_t i = 0; i < fresh.optimizers.size(); ++i) {
    nn::ReadAdam(archive, i == 0 ? "optimizer" : "optimizer_critic", *fresh.optimizers[i]);
    for (auto& group : fresh.optimizers[i]->param_groups()) {
      static_cast<torch::optim::AdamOptions&>(group.options())
          .lr(config_.learning_rate)
          .eps(config_.adam_eps);
    }
  }

  std::array<ReturnNormaliser, kMaxValueHeads> norms = norms_;
  for (int h = 0; h < StoredNormalisers(); ++h) {
    torch::Tensor tensor;
    archive.read(kNormaliserNames[h], tensor);
    IMCA_ASSIGN_OR_RETURN(norms[h], ReturnNormaliser::FromTensor(config_.value_norm, tensor, kNormaliserNames[h]));
  }
  torch::Tensor generator_state;
  archive.read("generator", generator_state);
  at::Generator generator = at::detail::createCPUGenerator();
  generator.set_state(generator_state);

  model_ = std::move(fresh);
  norms_ = norms;
  generator_ = std::move(generator);
  return absl::OkStatus();
}

// ---------------------------------------------------------------------------

namespace {

constexpr EnumName<PpoObjective> kObjectiveNames[] = {{PpoObjective::kBehaviour, "behaviour"},
                                                      {PpoObjective::kDecoupled, "decoupled"}};

}  // namespace

std::string PpoObjectiveName(PpoObjective objective) { return NameOf(objective, kObjectiveNames); }
std::vector<std::string> PpoObjectiveNames() { return Names(kObjectiveNames); }

absl::StatusOr<PpoObjective> ParsePpoObjective(const std::string& name) {
  return ParseName(name, kObjectiveNames);
}

PpoTrainer::PpoTrainer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
PpoTrainer::~PpoTrainer() = default;

absl::StatusOr<std::unique_ptr<PpoTrainer>> PpoTrainer::Create(const PpoConfig& config, int obs_dim,
                                                               int critic_dim, int num_actions) {
  const auto invalid = [](const std::string& what) {
    return absl::InvalidArgumentError(absl::StrCat("PpoTrainer: ", what));
  };
  if (obs_dim <= 0) return invalid(absl::StrCat("obs_dim must be > 0, got ", obs_dim));
  if (critic_dim <= 0) return invalid(absl::StrCat("critic_dim must be > 0, got ", critic_dim));
  if (num_actions <= 0) return invalid(absl::StrCat("num_actions must be > 0, got ", num_actions));
  if (config.hidden <= 0) {
    return invalid(absl::StrCat("config.hidden must be > 0, got ", config.hidden));
  }
  if (!(config.learning_rate > 0)) return invalid("config.learning_rate must be > 0");
  if (!(config.adam_eps > 0)) return invalid("config.adam_eps must be > 0");
  if (!(config.clip > 0)) return invalid("config.clip must be > 0");
  if (!(config.value_coef >= 0)) return invalid("config.value_coef must be >= 0");
  if (!(config.entropy_coef >= 0)) return invalid("config.entropy_coef must be >= 0");
  if (!(config.max_grad_norm > 0)) return invalid("config.max_grad_norm must be > 0");
  if (config.epochs <= 0) {
    return invalid(absl::StrCat("config.epochs must be > 0, got ", config.epochs));
  }
  if (config.minibatches <= 0) {
    return invalid(absl::StrCat("config.minibatches must be > 0, got ", config.minibatches));
  }
  if (config.threads <= 0) {
    return invalid(absl::StrCat("config.threads must be > 0, got ", config.threads));
  }
  if (config.value_heads < 1 || config.value_heads > 3) {
    return invalid(absl::StrCat("config.value_heads must be 1, 2 or 3, got ", config.value_heads));
  }
  if (!(config.hidden_gain > 0)) return invalid("config.hidden_gain must be > 0");
  if (!(config.value_clip >= 0)) return invalid("config.value_clip must be >= 0");
  if (!(config.huber_delta >= 0)) return invalid("config.huber_delta must be >= 0");
  return nn::TorchCall("PpoTrainer", [&]() -> absl::StatusOr<std::unique_ptr<PpoTrainer>> {
    return std::unique_ptr<PpoTrainer>(
        new PpoTrainer(std::make_unique<Impl>(config, obs_dim, critic_dim, num_actions)));
  });
}

absl::Status PpoTrainer::Values(const float* critic_inputs, int64_t batch, float* v_ext,
                                float* v_int, float* v_voi) {
  if (batch <= 0) return absl::OkStatus();
  return nn::TorchCall("critic forward", [&] {
    torch::NoGradGuard no_grad;
    // from_blob does not copy; the forward pass only reads its input.
    const torch::Tensor x = torch::from_blob(const_cast<float*>(critic_inputs),
                                             {batch, impl_->critic_dim_}, torch::kFloat32);
    const torch::Tensor out = impl_->model_.critic->forward(x).to(torch::kFloat64).contiguous();
    const auto v = out.accessor<double, 2>();
    float* outputs[] = {v_ext, v_int, v_voi};
    for (int h = 0; h < kMaxValueHeads; ++h) {
      if (outputs[h] == nullptr) continue;
      if (h >= impl_->config_.value_heads) {
        std::fill(outputs[h], outputs[h] + batch, 0.0f);
        continue;
      }
      const double std = impl_->norms_[h].std(), mean = impl_->norms_[h].mean();
      for (int64_t i = 0; i < batch; ++i) outputs[h][i] = static_cast<float>(v[i][h] * std + mean);
    }
  });
}

absl::StatusOr<PpoStats> PpoTrainer::Train(const PpoBatch& batch) {
  IMCA_RETURN_IF_ERROR(impl_->ValidateBatch(batch));
  return nn::TorchCall("PPO training failed", [&]() -> absl::StatusOr<PpoStats> { return impl_->Train(batch); });
}

v1::Policy PpoTrainer::ExportPolicy(int64_t version) const {
  return nn::ExportPolicy(impl_->config_.layer_norm ? v1::Policy::MLP_TANH_LAYERNORM : v1::Policy::MLP_TANH, version,
                          impl_->obs_dim_, impl_->num_actions_, {impl_->model_.actor.get()}, /*per_agent=*/false);
}

absl::Status PpoTrainer::Save(const std::string& path) const {
  return WriteFileAtomically(path, [&](std::ostream& out) {
    return nn::TorchCall(absl::StrCat("saving checkpoint ", path), [&] {
      torch::serialize::OutputArchive archive;
      impl_->WriteTo(archive);
      archive.save_to(out);
    });
  });
}

absl::Status PpoTrainer::Load(const std::string& path) {
  torch::serialize::InputArchive archive;
  IMCA_RETURN_IF_ERROR(nn::TorchCall(absl::StrCat("reading checkpoint ", path), [&] { archive.load_from(path); }));
  // The file parsed; a missing entry or a bad tensor means it does not fit.
  return nn::TorchCall(
      absl::StrCat("checkpoint ", path, " does not fit this trainer"), [&] { return impl_->ReadFrom(archive, path); },
      absl::StatusCode::kInvalidArgument);
}

int PpoTrainer::obs_dim() const { return impl_->obs_dim_; }
int PpoTrainer::critic_dim() const { return impl_->critic_dim_; }
int PpoTrainer::num_actions() const { return impl_->num_actions_; }

}  // namespace imca::learner
