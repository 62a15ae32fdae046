#include "learner/algorithms/maddpg/maddpg.h"

#include <ATen/CPUGeneratorImpl.h>
#include <torch/torch.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "common/base/lap.h"
#include "common/base/status_macros.h"
#include "common/env/featurizer.h"
#include "common/nn/archive.h"
#include "common/nn/mlp.h"
#include "common/nn/policy_export.h"
#include "common/nn/torch_status.h"
#include "learner/algorithms/maddpg/maddpg_internal.h"
#include "learner/algorithms/registry.h"

namespace imca::learner {
namespace {

constexpr char kTag[] = "IMCA-MADDPG-1";

absl::Status ValidateConfig(const LearnerConfig& config) {
  IMCA_ASSIGN_OR_RETURN(const MaddpgConfig* options, CheckedOptions<MaddpgConfig>(config));
  const MaddpgConfig& m = *options;
  // Messages name the config field and its learner flag.
  const auto bad = [](const char* field, const char* flag, const std::string& why) {
    return absl::InvalidArgumentError(absl::StrCat("maddpg.", field, " (--", flag, ") ", why));
  };
  if (m.hidden < 1) return bad("hidden", "maddpg_hidden", "must be >= 1");
  if (!(m.actor_lr > 0) || !std::isfinite(m.actor_lr)) return bad("actor_lr", "maddpg_actor_lr", "must be > 0");
  if (!(m.critic_lr > 0) || !std::isfinite(m.critic_lr)) return bad("critic_lr", "maddpg_critic_lr", "must be > 0");
  if (!(m.tau > 0 && m.tau <= 1)) return bad("tau", "maddpg_tau", "must be in (0, 1]");
  if (!(m.max_grad_norm > 0)) return bad("max_grad_norm", "maddpg_max_grad_norm", "must be > 0");
  if (!(m.policy_reg >= 0) || !std::isfinite(m.policy_reg)) return bad("policy_reg", "maddpg_policy_reg", "must be >= 0");
  if (m.batch_size < 1) return bad("batch_size", "maddpg_batch", "must be >= 1");
  if (m.buffer_transitions < m.batch_size) return bad("buffer_transitions", "maddpg_buffer", "must be >= the batch");
  if (m.learning_starts < m.batch_size || m.learning_starts > m.buffer_transitions) {
    return bad("learning_starts", "maddpg_learning_starts", "must be between the batch and the buffer size");
  }
  if (!(m.updates_per_step > 0 && m.updates_per_step <= 16)) {
    return bad("updates_per_step", "updates_per_step", "must be in (0, 16]");
  }
  if (!(config.gamma > 0 && config.gamma <= 1)) return absl::InvalidArgumentError("gamma (--gamma) must be in (0, 1]");
  return absl::OkStatus();
}

// One replay transition: two states, n actions, n rewards, done.
int64_t ReplayTransitionBytes(const env::Scenario& scenario) {
  return static_cast<int64_t>(sizeof(int32_t)) * (2 * scenario.state_size() + scenario.num_agents()) +
         static_cast<int64_t>(sizeof(float)) * scenario.num_agents() + 1;
}

torch::Tensor FromFloats(const std::vector<float>& v, std::vector<int64_t> shape) {
  return torch::from_blob(const_cast<float*>(v.data()), shape, torch::kFloat32).clone();
}

}  // namespace

// A sampled batch as tensors.
struct Sample {
  torch::Tensor obs;       // [B, n, D]
  torch::Tensor next_obs;  // [B, n, D]
  torch::Tensor actions;   // [B, n, A] one-hot
  torch::Tensor rewards;   // [B, n]
  torch::Tensor alive;     // [B, 1]: 1 - done
};

// Networks and optimisers: what Load swaps in whole.
struct Nets {
  std::vector<nn::Mlp> actors, critics, target_actors, target_critics;  // 1 each when shared, else n.
  std::unique_ptr<torch::optim::Adam> actor_optimizer, critic_optimizer;
};

struct Maddpg::Impl {
  Impl(const env::Scenario* scenario, const LearnerConfig& config)
      : scenario(scenario),
        config(config),
        m(OptionsOf<MaddpgConfig>(config)),
        featurizer(*scenario),
        n(scenario->num_agents()),
        k(scenario->state_size()),
        A(scenario->num_actions()),
        D(featurizer.obs_dim()),
        generator(at::detail::createCPUGenerator(nn::SubSeed(config.seed, uint64_t{1} << 32))) {
    nets = BuildNets();
  }

  // Critic input per agent row: joint observation, joint one-hot action and,
  // with shared parameters, the agent id.
  int64_t critic_in() const { return int64_t{n} * D + int64_t{n} * A + (m.share_parameters ? n : 0); }
  int networks() const { return m.share_parameters ? 1 : n; }

  Nets BuildNets() const {
    Nets nets;
    // Orthogonal init (the reference uses TF's Glorot default): hidden gain
    // sqrt 2, the actor's output 0.01 (a near-uniform first policy), the
    // critic's 1; target copies start equal.
    const auto mlp = [&](int64_t in, int64_t out, double last_gain, uint64_t stream) {
      return nn::Mlp(nn::MlpOptions({in, m.hidden, m.hidden, out})
                         .activation(nn::Activation::kRelu)
                         .hidden_gain(std::sqrt(2.0))
                         .last_gain(last_gain)
                         .seed(nn::SubSeed(config.seed, stream)));
    };
    std::vector<torch::Tensor> actor_params, critic_params;
    for (int i = 0; i < networks(); ++i) {
      // Streams 2i + 1 (actor i) and 2i + 2 (critic i); targets are copied.
      nets.actors.push_back(mlp(D, A, 0.01, 2 * i + 1));
      nets.critics.push_back(mlp(critic_in(), 1, 1.0, 2 * i + 2));
      nets.target_actors.push_back(mlp(D, A, 0.01, 2 * i + 1));
      nets.target_critics.push_back(mlp(critic_in(), 1, 1.0, 2 * i + 2));
      nn::SoftUpdate(*nets.target_actors.back(), *nets.actors.back(), 1.0);
      nn::SoftUpdate(*nets.target_critics.back(), *nets.critics.back(), 1.0);
      for (auto& p : nets.target_actors.back()->parameters()) p.set_requires_grad(false);
      for (auto& p : nets.target_critics.back()->parameters()) p.set_requires_grad(false);
      for (auto& p : nets.actors.back()->parameters()) actor_params.push_back(p);
      for (auto& p : nets.critics.back()->parameters()) critic_params.push_back(p);
    }
    nets.actor_optimizer = std::make_unique<torch::optim::Adam>(actor_params, torch::optim::AdamOptions(m.actor_lr));
    nets.critic_optimizer =
        std::make_unique<torch::optim::Adam>(critic_params, torch::optim::AdamOptions(m.critic_lr));
    return nets;
  }

  // Logits [B, n, A] of observations [B, n, D].
  torch::Tensor Logits(std::vector<nn::Mlp>& actors, const torch::Tensor& obs) const {
    const int64_t B = obs.size(0);
    if (m.share_parameters) return actors[0]->forward(obs.reshape({B * n, D})).view({B, n, A});
    std::vector<torch::Tensor> out;
    for (int i = 0; i < n; ++i) out.push_back(actors[i]->forward(obs.select(1, i)));
    return torch::stack(out, 1);
  }

  // Q_i [B, n] of joint observations [B, n*D] and per-agent joint actions
  // [B, n, n*A] (row i: the joint action agent i's critic judges). The
  // critic's input is [joint obs | joint action | agent id (shared)]; its
  // first layer is applied in parts, the joint observation's once per sample
  // rather than once per agent (the same sum, a third of the work on three
  // agents), then the network continues (nn::MlpImpl::ForwardFrom).
  torch::Tensor Q(std::vector<nn::Mlp>& critics, const torch::Tensor& joint_obs, const torch::Tensor& joint_actions) const {
    const int64_t B = joint_obs.size(0), obs_in = int64_t{n} * D;
    const torch::Tensor rest =
        m.share_parameters ? torch::cat({joint_actions, torch::eye(n).unsqueeze(0).expand({B, n, n})}, 2)
                           : joint_actions;  // [B, n, R]
    const auto head = [&](nn::Mlp& net, const torch::Tensor& own) {  // own [B, m, R] -> [B, m]
      const torch::nn::Linear& first = net->layers()[0];
      const torch::Tensor pre = torch::matmul(joint_obs, first->weight.narrow(1, 0, obs_in).t()).unsqueeze(1) +
                                torch::matmul(own, first->weight.narrow(1, obs_in, own.size(2)).t()) + first->bias;
      return net->ForwardFrom(pre, 0).squeeze(-1);
    };
    if (m.share_parameters) return head(critics[0], rest);
    std::vector<torch::Tensor> out;
    for (int i = 0; i < n; ++i) out.push_back(head(critics[i], rest.narrow(1, i, 1)).squeeze(1));
    return torch::stack(out, 1);
  }

  // The same joint action [B, n, A] for every agent's critic: [B, n, n*A].
  torch::Tensor Everyone(const torch::Tensor& actions) const {
    const int64_t B = actions.size(0);
    return actions.reshape({B, 1, n * A}).expand({B, n, n * A});
  }

  // Critic targets y [B, n]: r + gamma (1 - done) Q'(o', a') with a'_k a
  // hard Gumbel sample of target actor k (the reference samples the target
  // actors; hard, because the critic learns on one-hot actions).
  torch::Tensor Targets(const Sample& s) {
    torch::NoGradGuard no_grad;
    const int64_t B = s.obs.size(0);
    const torch::Tensor next_logits = Logits(nets.target_actors, s.next_obs);
    const torch::Tensor next_actions = internal::GumbelSoftmaxHard(next_logits, Uniform(next_logits.sizes()));
    const torch::Tensor q_next = Q(nets.target_critics, s.next_obs.reshape({B, n * D}), Everyone(next_actions));
    return s.rewards + config.gamma * s.alive * q_next;
  }

  // Uniform noise in (0, 1) from the algorithm's generator.
  torch::Tensor Uniform(at::IntArrayRef shape) {
    return torch::rand(shape, generator).clamp(std::numeric_limits<float>::min(), 1.0f - 1e-7f);
  }

  void Insert(const int32_t* state, const int32_t* next_state, const int32_t* actions, const float* rewards,
              bool done) {
    const int64_t slot = size < m.buffer_transitions ? size : head;
    if (size == 0) {  // The whole replay at once: no growth by doubling.
      states.reserve(m.buffer_transitions * k);
      next_states.reserve(m.buffer_transitions * k);
      actions_.reserve(m.buffer_transitions * n);
      rewards_.reserve(m.buffer_transitions * n);
      done_.reserve(m.buffer_transitions);
    }
    if (size < m.buffer_transitions) {
      states.resize((size + 1) * k);
      next_states.resize((size + 1) * k);
      actions_.resize((size + 1) * n);
      rewards_.resize((size + 1) * n);
      done_.resize(size + 1);
      ++size;
    } else {
      head = (head + 1) % m.buffer_transitions;
    }
    std::copy(state, state + k, &states[slot * k]);
    std::copy(next_state, next_state + k, &next_states[slot * k]);
    std::copy(actions, actions + n, &actions_[slot * n]);
    std::copy(rewards, rewards + n, &rewards_[slot * n]);
    done_[slot] = done;
  }

  std::vector<int64_t> SampleIndices(int count) {
    const torch::Tensor idx = torch::randint(size, {count}, generator, torch::kInt64);
    return std::vector<int64_t>(idx.data_ptr<int64_t>(), idx.data_ptr<int64_t>() + count);
  }

  Sample Gather(const std::vector<int64_t>& indices) const {
    const int64_t B = static_cast<int64_t>(indices.size());
    std::vector<float> obs(B * n * D), next_obs(B * n * D), onehot(B * n * A, 0.0f), rewards(B * n), alive(B);
    for (int64_t b = 0; b < B; ++b) {
      const int64_t i = indices[b];
      for (int a = 0; a < n; ++a) {
        featurizer.Observe(&states[i * k], a, &obs[(b * n + a) * D]);
        featurizer.Observe(&next_states[i * k], a, &next_obs[(b * n + a) * D]);
        onehot[(b * n + a) * A + actions_[i * n + a]] = 1.0f;
        rewards[b * n + a] = rewards_[i * n + a];
      }
      alive[b] = done_[i] ? 0.0f : 1.0f;
    }
    return Sample{FromFloats(obs, {B, n, D}), FromFloats(next_obs, {B, n, D}), FromFloats(onehot, {B, n, A}),
                  FromFloats(rewards, {B, n}), FromFloats(alive, {B, 1})};
  }

  // Per-agent losses [n] -> one: their mean for shared networks, their sum
  // for separate ones (each network then sees its own agent's loss).
  torch::Tensor AgentsLoss(const torch::Tensor& per_agent) const {
    return m.share_parameters ? per_agent.mean() : per_agent.sum();
  }

  static void SetRequiresGrad(std::vector<nn::Mlp>& nets, bool on) {
    for (auto& net : nets) {
      for (auto& p : net->parameters()) p.set_requires_grad(on);
    }
  }

  // Clips each network's gradient norm at max_norm and steps `optimizer`,
  // unless the loss or a norm is not finite (clip_grad_norm_'s norm is then
  // not finite either, so it is the check); adds the mean norm to *grad.
  // Returns whether it stepped.
  bool ClipAndStep(const torch::Tensor& loss, std::vector<nn::Mlp>& nets, torch::optim::Adam& optimizer,
                   double* grad) const {
    double total = 0;
    for (auto& net : nets) total += torch::nn::utils::clip_grad_norm_(net->parameters(), m.max_grad_norm);
    if (!std::isfinite(loss.item<double>()) || !std::isfinite(total)) return false;
    optimizer.step();
    *grad += total / nets.size();
    return true;
  }

  // One gradient step of critics and actors on `s`, then the soft target
  // updates. A step whose loss or gradient is not finite is skipped.
  void Update(const Sample& s) {
    Clock::time_point lap = Clock::now();
    const int64_t B = s.obs.size(0);
    const torch::Tensor joint_obs = s.obs.reshape({B, n * D});
    const torch::Tensor y = Targets(s);
    // Critic: mean over samples of (Q_i - y_i)^2; one shared critic takes
    // the mean over agents too, separate critics the sum, so that each gets
    // its own agent's loss as in the reference (the clip then means the same).
    const torch::Tensor q = Q(nets.critics, joint_obs, Everyone(s.actions));
    const torch::Tensor critic_loss = AgentsLoss((q - y).pow(2).mean(0));
    // Actor: agent i's own action the straight-through Gumbel sample of its
    // actor, the others' those of the replay (the reference code).
    const torch::Tensor logits = Logits(nets.actors, s.obs);
    const torch::Tensor sampled = internal::GumbelSoftmaxHard(logits, Uniform({B, n, A}));  // [B, n, A]
    const torch::Tensor own = torch::eye(n).view({1, n, n, 1});                         // [1, i, slot, 1]
    const torch::Tensor joint =
        (own * sampled.unsqueeze(1) + (1 - own) * s.actions.unsqueeze(1)).reshape({B, n, n * A});
    sums.seconds_forward += Lap(lap);

    nets.critic_optimizer->zero_grad();
    critic_loss.backward();
    sums.seconds_backward += Lap(lap);
    double grad = 0;
    const bool critic_ok = ClipAndStep(critic_loss, nets.critics, *nets.critic_optimizer, &grad);
    sums.seconds_optimizer += Lap(lap);

    // The actor's loss goes through the critic as it is now (after its step,
    // as in the reference code); only the actors are stepped, so the
    // critics' parameters need no gradient on this pass.
    SetRequiresGrad(nets.critics, false);
    const torch::Tensor q_actor = Q(nets.critics, joint_obs, joint);
    const torch::Tensor actor_loss =
        AgentsLoss(-q_actor.mean(0) + m.policy_reg * logits.pow(2).mean(2).mean(0));
    sums.seconds_forward += Lap(lap);
    nets.actor_optimizer->zero_grad();
    actor_loss.backward();
    SetRequiresGrad(nets.critics, true);
    sums.seconds_backward += Lap(lap);
    const bool actor_ok = ClipAndStep(actor_loss, nets.actors, *nets.actor_optimizer, &grad);
    for (int i = 0; i < networks(); ++i) {
      nn::SoftUpdate(*nets.target_actors[i], *nets.actors[i], m.tau);
      nn::SoftUpdate(*nets.target_critics[i], *nets.critics[i], m.tau);
    }
    sums.seconds_optimizer += Lap(lap);
    if ((!critic_ok || !actor_ok) && sums.minibatches_skipped++ == 0) {
      sums.skip_reason = !critic_ok ? "critic loss or gradient not finite" : "actor loss or gradient not finite";
    }
    torch::NoGradGuard no_grad;
    const torch::Tensor log_p = torch::log_softmax(logits.detach(), -1);
    actor_loss_sum += actor_loss.item<double>();
    critic_loss_sum += critic_loss.item<double>();
    sums.entropy += -(log_p.exp() * log_p).sum(-1).mean().item<double>();
    sums.grad_norm += grad / 2;
    ++sums.updates;
    ++updates;
    sums.seconds_optimizer += Lap(lap);
  }

  const env::Scenario* scenario;
  const LearnerConfig config;
  const MaddpgConfig m;
  const env::Featurizer featurizer;
  const int n, k, A, D;
  Nets nets;
  at::Generator generator;  // Replay sampling and Gumbel noise; checkpointed.
  // The replay, FIFO once full: compact states, actions, summed rewards, done.
  std::vector<int32_t> states, next_states, actions_;
  std::vector<float> rewards_;
  std::vector<uint8_t> done_;
  int64_t size = 0, head = 0;
  // Updates owed: updates_per_step per step inserted while the replay holds
  // learning_starts; one update is taken for every whole one.
  double credit = 0;
  int64_t updates = 0;
  // The current iteration's sums and timings (Train turns the losses,
  // entropy and grad norm into means).
  IterationStats sums;
  double actor_loss_sum = 0, critic_loss_sum = 0;  // Over the iteration's gradient steps.
};

absl::StatusOr<std::unique_ptr<Maddpg>> Maddpg::Create(const env::Scenario* scenario, const LearnerConfig& config) {
  IMCA_RETURN_IF_ERROR(ValidateConfig(config));
  const int64_t per_transition = ReplayTransitionBytes(*scenario);
  const MaddpgConfig& m = OptionsOf<MaddpgConfig>(config);
  if (m.buffer_transitions > config.max_batch_bytes / per_transition) {
    return absl::InvalidArgumentError(absl::StrFormat(
        "maddpg.buffer_transitions (--maddpg_buffer): a replay of %d transitions needs %.0f MB here, over the "
        "learner's memory cap of %.0f MB (--max_batch_mb)",
        m.buffer_transitions, m.buffer_transitions * (per_transition / 1e6),
        config.max_batch_bytes / 1e6));
  }
  IMCA_ASSIGN_OR_RETURN(std::unique_ptr<Impl> impl,
                        nn::TorchCall("maddpg networks", [&]() -> absl::StatusOr<std::unique_ptr<Impl>> {
                          return std::make_unique<Impl>(scenario, config);
                        }));
  return std::unique_ptr<Maddpg>(new Maddpg(std::move(impl)));
}

Maddpg::Maddpg(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Maddpg::~Maddpg() = default;

FeaturisedUnroll Maddpg::Featurise(v1::Unroll unroll) const {
  FeaturisedUnroll q;
  q.unroll = std::move(unroll);
  return q;
}

int64_t Maddpg::IterationBytes(int64_t steps) const {
  // Each queued step: states and next states (K ints each), n actions,
  // n rewards (and the proto's other per-agent fields: a generous 4x).
  const int64_t per_step = 4 * static_cast<int64_t>(sizeof(int32_t)) * (2 * impl_->k + 4 * impl_->n);
  if (steps > std::numeric_limits<int64_t>::max() / per_step) return std::numeric_limits<int64_t>::max();
  return steps * per_step;
}

int64_t Maddpg::ReplayBytes() const {
  return impl_->m.buffer_transitions * ReplayTransitionBytes(*impl_->scenario);
}
int64_t Maddpg::replay_size() const { return impl_->size; }
int64_t Maddpg::updates() const { return impl_->updates; }

absl::Status Maddpg::Add(const FeaturisedUnroll& queued) {
  Impl& s = *impl_;
  const v1::Unroll& u = queued.unroll;
  const int n = s.n, k = s.k;
  const int64_t T = u.length(), E = u.num_envs();
  const bool limit_terminal = s.config.time_limit == TimeLimit::kTerminal;
  const float c_int = static_cast<float>(s.config.intrinsic_coef);
  Clock::time_point lap = Clock::now();
  std::vector<float> rewards(n);
  for (int64_t row = 0; row < T * E; ++row) {
    for (int a = 0; a < n; ++a) {
      rewards[a] = u.rewards(row * n + a) + c_int * u.intrinsic_rewards(row * n + a);
    }
    // next_states holds the state each step reached (the end state where an
    // episode ended, states[t+1] otherwise).
    const bool done = u.terminated(row) || (limit_terminal && u.truncated(row));
    s.Insert(u.states().data() + row * k, u.next_states().data() + row * k, u.actions().data() + row * n,
             rewards.data(), done);
    if (s.size >= s.m.learning_starts) s.credit += s.m.updates_per_step;
  }
  s.sums.seconds_copy += Lap(lap);
  return nn::TorchCall("maddpg update", [&] {
    while (s.credit >= 1.0) {
      s.credit -= 1.0;
      Clock::time_point sample_lap = Clock::now();
      const Sample sample = s.Gather(s.SampleIndices(s.m.batch_size));
      s.sums.seconds_prepare += Lap(sample_lap);
      s.Update(sample);
    }
  });
}

absl::StatusOr<IterationStats> Maddpg::Train() {
  Impl& s = *impl_;
  IterationStats stats = s.sums;
  const double u = std::max<int64_t>(stats.updates, 1);
  stats.values = {{"actor_loss", s.actor_loss_sum / u},
                  {"critic_loss", s.critic_loss_sum / u},
                  {"replay_size", static_cast<double>(s.size)}};
  stats.entropy /= u;
  stats.grad_norm /= u;
  s.sums = IterationStats();
  s.actor_loss_sum = s.critic_loss_sum = 0;
  return stats;
}

v1::Policy Maddpg::ExportPolicy(int64_t version) const {
  const Impl& s = *impl_;
  std::vector<const nn::MlpImpl*> actors;
  for (int i = 0; i < s.networks(); ++i) actors.push_back(s.nets.actors[i].get());
  return nn::ExportPolicy(v1::Policy::MLP_RELU, version, s.D, s.A, actors, /*per_agent=*/!s.m.share_parameters);
}

// The archive: "dims" int64 [n, obs_dim, num_actions, hidden, shared],
// sub-archives "actor<i>", "critic<i>", "target_actor<i>", "target_critic<i>",
// "actor_optimizer", "critic_optimizer", "generator", and float64
// "counters" [updates, credit]. The replay is not saved (see maddpg.h).
absl::Status Maddpg::Save(const std::string& path) const {
  const Impl& s = *impl_;
  return nn::SaveArchive(path, kTag, [&](torch::serialize::OutputArchive& archive) {
    archive.write("dims", torch::tensor({int64_t{s.n}, int64_t{s.D}, int64_t{s.A}, int64_t{s.m.hidden},
                                         int64_t{s.m.share_parameters}},
                                        torch::kInt64));
    const auto save = [&](const std::string& name, const nn::Mlp& net) {
      torch::serialize::OutputArchive sub(archive.compilation_unit());
      net->save(sub);
      archive.write(name, sub);
    };
    for (int i = 0; i < s.networks(); ++i) {
      save(absl::StrCat("actor", i), s.nets.actors[i]);
      save(absl::StrCat("critic", i), s.nets.critics[i]);
      save(absl::StrCat("target_actor", i), s.nets.target_actors[i]);
      save(absl::StrCat("target_critic", i), s.nets.target_critics[i]);
    }
    nn::WriteAdam(archive, "actor_optimizer", *s.nets.actor_optimizer);
    nn::WriteAdam(archive, "critic_optimizer", *s.nets.critic_optimizer);
    archive.write("generator", s.generator.get_state());
    archive.write("counters", torch::tensor({static_cast<double>(s.updates), s.credit}, torch::kFloat64));
  });
}

absl::Status Maddpg::Load(const std::string& path) {
  Impl& s = *impl_;
  absl::Status fits;
  const absl::Status loaded = nn::LoadArchive(path, kTag, [&](torch::serialize::InputArchive& archive) {
    torch::Tensor dims;
    archive.read("dims", dims);
    const std::vector<int64_t> want = {s.n, s.D, s.A, s.m.hidden, int64_t{s.m.share_parameters}};
    const torch::Tensor d = dims.contiguous();
    const std::vector<int64_t> have(d.data_ptr<int64_t>(), d.data_ptr<int64_t>() + d.numel());
    if (have != want) {
      fits = absl::InvalidArgumentError(absl::StrCat("checkpoint ", path,
                                                     " has (agents, obs_dim, num_actions, hidden, shared) = (",
                                                     absl::StrJoin(have, ", "), "), this learner has (",
                                                     absl::StrJoin(want, ", "), ")"));
      return;
    }
    Nets fresh = s.BuildNets();
    const auto load = [&](const std::string& name, nn::Mlp& net) {
      torch::serialize::InputArchive sub;
      archive.read(name, sub);
      net->load(sub);
    };
    for (int i = 0; i < s.networks(); ++i) {
      load(absl::StrCat("actor", i), fresh.actors[i]);
      load(absl::StrCat("critic", i), fresh.critics[i]);
      load(absl::StrCat("target_actor", i), fresh.target_actors[i]);
      load(absl::StrCat("target_critic", i), fresh.target_critics[i]);
    }
    nn::ReadAdam(archive, "actor_optimizer", *fresh.actor_optimizer);
    nn::ReadAdam(archive, "critic_optimizer", *fresh.critic_optimizer);
    torch::Tensor generator_state, counters;
    archive.read("generator", generator_state);
    archive.read("counters", counters);
    at::Generator generator = at::detail::createCPUGenerator();
    generator.set_state(generator_state);
    const torch::Tensor c = counters.to(torch::kFloat64).contiguous();
    TORCH_CHECK(c.numel() == 2, "counters is not [2]");
    s.nets = std::move(fresh);
    s.generator = std::move(generator);
    s.updates = static_cast<int64_t>(c[0].item<double>());
    s.credit = c[1].item<double>();
  });
  if (!fits.ok()) return fits;
  if (absl::IsFailedPrecondition(loaded) || absl::IsDataLoss(loaded)) {
    return absl::InvalidArgumentError(loaded.message());
  }
  if (absl::IsNotFound(loaded)) return absl::InternalError(loaded.message());
  return loaded;
}

void Maddpg::InsertForTest(const Transition& t) {
  impl_->Insert(t.state.data(), t.next_state.data(), t.actions.data(), t.rewards.data(), t.done);
}

absl::StatusOr<std::vector<float>> Maddpg::CriticTargetsForTest(int64_t index) {
  return nn::TorchCall("critic targets", [&]() -> absl::StatusOr<std::vector<float>> {
    const torch::Tensor y = impl_->Targets(impl_->Gather({index})).contiguous();
    return std::vector<float>(y.data_ptr<float>(), y.data_ptr<float>() + y.numel());
  });
}

std::vector<int64_t> Maddpg::SampleIndicesForTest(int count) { return impl_->SampleIndices(count); }

absl::Status Maddpg::UpdateForTest() {
  return nn::TorchCall("maddpg update", [&] {
    std::vector<int64_t> all(impl_->size);
    for (int64_t i = 0; i < impl_->size; ++i) all[i] = i;
    impl_->Update(impl_->Gather(all));
  });
}

std::vector<float> Maddpg::ProbabilitiesForTest(const std::vector<int32_t>& state) {
  Impl& s = *impl_;
  std::vector<float> obs(s.n * s.D);
  for (int a = 0; a < s.n; ++a) s.featurizer.Observe(state.data(), a, &obs[a * s.D]);
  torch::NoGradGuard no_grad;
  const torch::Tensor p = torch::softmax(s.Logits(s.nets.actors, FromFloats(obs, {1, s.n, s.D})), -1).contiguous();
  return std::vector<float>(p.data_ptr<float>(), p.data_ptr<float>() + p.numel());
}

}  // namespace imca::learner
