#include "learner/algorithms/mappo/mappo.h"

#include <algorithm>
#include <memory>

#include "absl/strings/str_cat.h"
#include "common/base/lap.h"
#include "common/base/status_macros.h"
#include "learner/algorithms/mappo/gae.h"
#include "learner/algorithms/registry.h"

namespace imca::learner {

int MappoCriticDim(const env::Scenario& scenario, const LearnerConfig& config) {
  const env::Featurizer featurizer(scenario);
  const int n = scenario.num_agents();
  const CriticInput input = OptionsOf<MappoOptions>(config).critic_input;
  return (input == CriticInput::kJointObs ? n * featurizer.obs_dim() : featurizer.global_dim()) + n;
}

absl::StatusOr<std::unique_ptr<Mappo>> Mappo::Create(const env::Scenario* scenario, const LearnerConfig& config) {
  IMCA_ASSIGN_OR_RETURN(const MappoOptions* options, CheckedOptions<MappoOptions>(config));
  if (options->edti != (options->ppo.value_heads == 3)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "value_heads is ", options->ppo.value_heads,
        options->edti ? ": edti needs 3 (extrinsic, intrinsic, interaction)" : ": 3 heads are for edti only"));
  }
  if (!(config.gamma > 0 && config.gamma <= 1) || !(config.gamma_int > 0 && config.gamma_int <= 1) ||
      !(config.lambda >= 0 && config.lambda <= 1)) {
    return absl::InvalidArgumentError("gamma, gamma_int must be in (0,1] and lambda in [0,1]");
  }
  const env::Featurizer featurizer(*scenario);
  PpoConfig ppo = options->ppo;
  ppo.seed = config.seed;
  ppo.threads = config.threads;
  IMCA_ASSIGN_OR_RETURN(std::unique_ptr<PpoTrainer> trainer,
                        PpoTrainer::Create(ppo, featurizer.obs_dim(), MappoCriticDim(*scenario, config),
                                           scenario->num_actions()));
  return std::unique_ptr<Mappo>(new Mappo(scenario, config, *options, std::move(trainer)));
}

Mappo::Mappo(const env::Scenario* scenario, const LearnerConfig& config, const MappoOptions& options,
             std::unique_ptr<PpoTrainer> trainer)
    : scenario_(scenario),
      config_(config),
      options_(options),
      featurizer_(*scenario),
      trainer_(std::move(trainer)) {}

int64_t Mappo::IterationBytes(int64_t steps) const {
  const int64_t per_step = int64_t{scenario_->num_agents()} * (featurizer_.obs_dim() + critic_dim());
  const int64_t bytes_per_step = 4 * per_step * static_cast<int64_t>(sizeof(float));
  // Saturates instead of overflowing for absurd step counts.
  if (steps > std::numeric_limits<int64_t>::max() / bytes_per_step) return std::numeric_limits<int64_t>::max();
  return steps * bytes_per_step;
}

FeaturisedUnroll Mappo::Featurise(v1::Unroll unroll) const {
  const int n = scenario_->num_agents(), k = scenario_->state_size();
  const int obs_dim = featurizer_.obs_dim(), critic_dim = this->critic_dim();
  const int64_t T = unroll.length(), E = unroll.num_envs();
  Clock::time_point lap = Clock::now();
  FeaturisedUnroll q;
  q.obs.resize(T * E * n * obs_dim);
  q.critic_inputs.resize((T + 1) * E * n * critic_dim);
  for (int64_t row = 0; row < (T + 1) * E; ++row) {
    const int32_t* state = unroll.states().data() + row * k;
    float* obs = nullptr;  // The bootstrap states (row >= T * E) are not acted on.
    if (row < T * E) {
      obs = &q.obs[row * n * obs_dim];
      for (int a = 0; a < n; ++a) featurizer_.Observe(state, a, obs + a * obs_dim);
    }
    CriticInputsOf(state, obs, &q.critic_inputs[row * n * critic_dim]);
  }
  q.unroll = std::move(unroll);
  q.featurise_seconds = Lap(lap);
  return q;
}

void Mappo::CriticInputsOf(const int32_t* state, const float* obs, float* out) const {
  const int n = scenario_->num_agents(), obs_dim = featurizer_.obs_dim(), critic_dim = this->critic_dim();
  const int features = critic_dim - n;  // The part every agent shares; then the agent id.
  if (options_.critic_input == CriticInput::kState) {
    featurizer_.GlobalState(state, out);
  } else if (obs != nullptr) {
    std::copy(obs, obs + n * obs_dim, out);
  } else {
    for (int a = 0; a < n; ++a) featurizer_.Observe(state, a, out + a * obs_dim);
  }
  for (int a = 0; a < n; ++a) {
    float* row = out + a * critic_dim;
    if (a > 0) std::copy(out, out + features, row);
    std::fill(row + features, row + critic_dim, 0.0f);
    row[features + a] = 1.0f;
  }
}

absl::Status Mappo::Add(const FeaturisedUnroll& q) {
  PpoBatch* batch = &batch_;
  const int n = scenario_->num_agents();
  const int k = scenario_->state_size();
  const int obs_dim = featurizer_.obs_dim();
  const int critic_dim = this->critic_dim();
  const bool one_head = options_.ppo.value_heads == 1;
  const bool limit_terminal = config_.time_limit == TimeLimit::kTerminal;
  if (batch->size == 0) {  // Room for the whole batch (the last unroll may overshoot).
    batch->obs.reserve(config_.batch_steps * n * obs_dim);
    batch->critic_inputs.reserve(config_.batch_steps * n * critic_dim);
  }
  Clock::time_point lap = Clock::now();
  const v1::Unroll& u = q.unroll;
  const int64_t T = u.length(), E = u.num_envs(), M = E * n, B = T * M;
  // Critic inputs of states [T+1][E][n], featurised by Push.
  const std::vector<float>& inputs = q.critic_inputs;
  const bool edti = options_.edti;
  std::vector<float> v_ext((T + 1) * M), v_int((T + 1) * M), f_ext(B), f_int(B);
  std::vector<float> v_voi(edti ? (T + 1) * M : 0), f_voi(edti ? B : 0);
  IMCA_RETURN_IF_ERROR(
      trainer_->Values(inputs.data(), (T + 1) * M, v_ext.data(), v_int.data(), edti ? v_voi.data() : nullptr));
  // GAE reads final values only at truncated steps: evaluate just those
  // reached states (a few per unroll, not all T*E of them).
  std::vector<int64_t> truncated_rows;
  for (int64_t row = 0; row < T * E; ++row) {
    if (u.truncated(row) && !u.terminated(row) && !limit_terminal) truncated_rows.push_back(row);
  }
  if (!truncated_rows.empty()) {
    const int64_t rows = static_cast<int64_t>(truncated_rows.size()) * n;
    std::vector<float> final_inputs(rows * critic_dim), final_ext(rows), final_int(rows), final_voi(rows);
    for (size_t i = 0; i < truncated_rows.size(); ++i) {
      CriticInputsOf(u.next_states().data() + truncated_rows[i] * k, nullptr, &final_inputs[i * n * critic_dim]);
    }
    IMCA_RETURN_IF_ERROR(trainer_->Values(final_inputs.data(), rows, final_ext.data(), final_int.data(),
                                          edti ? final_voi.data() : nullptr));
    for (size_t i = 0; i < truncated_rows.size(); ++i) {
      for (int a = 0; a < n; ++a) {
        f_ext[truncated_rows[i] * n + a] = final_ext[i * n + a];
        f_int[truncated_rows[i] * n + a] = final_int[i * n + a];
        if (edti) f_voi[truncated_rows[i] * n + a] = final_voi[i * n + a];
      }
    }
  }
  adding_.seconds_values += Lap(lap);
  std::unique_ptr<bool[]> terminated(new bool[B]), truncated(new bool[B]);
  for (int64_t row = 0; row < T * E; ++row) {
    for (int a = 0; a < n; ++a) {
      // kTerminal: the step limit cuts the return like termination.
      terminated[row * n + a] = u.terminated(row) || (limit_terminal && u.truncated(row));
      truncated[row * n + a] = u.truncated(row) && !limit_terminal;
    }
  }
  std::vector<float> adv_ext(B), ret_ext(B), adv_int(B, 0.0f), ret_int(B, 0.0f);
  if (one_head) {
    // One value of r_ext + c_int * r_int, discounted with gamma.
    std::vector<float> rewards(B);
    for (int64_t i = 0; i < B; ++i) {
      rewards[i] = u.rewards(i) + static_cast<float>(config_.intrinsic_coef) * u.intrinsic_rewards(i);
    }
    ComputeGae(T, M, rewards.data(), v_ext.data(), f_ext.data(), terminated.get(), truncated.get(),
               config_.gamma, config_.lambda, adv_ext.data(), ret_ext.data());
  } else {
    ComputeGae(T, M, u.rewards().data(), v_ext.data(), f_ext.data(), terminated.get(), truncated.get(),
               config_.gamma, config_.lambda, adv_ext.data(), ret_ext.data());
    ComputeGae(T, M, u.intrinsic_rewards().data(), v_int.data(), f_int.data(), terminated.get(),
               truncated.get(), config_.gamma_int, config_.lambda, adv_int.data(), ret_int.data());
  }
  std::vector<float> adv_voi(edti ? B : 0), ret_voi(edti ? B : 0);
  if (edti) {
    // EDTI's value of interaction, from the values of the influenced agents
    // at the next state (all heads, one GAE of its own with the third head).
    std::vector<float> voi(B);
    EdtiInteractionRewards(T, E, n, u.influences().data(), v_ext.data(), v_int.data(), u.rewards().data(),
                           u.intrinsic_rewards().data(), static_cast<float>(config_.gamma),
                           options_.edti_coefficients, voi.data());
    ComputeGae(T, M, voi.data(), v_voi.data(), f_voi.data(), terminated.get(), truncated.get(), config_.gamma,
               config_.lambda, adv_voi.data(), ret_voi.data());
    for (int64_t i = 0; i < B; ++i) voi_sum_ += voi[i];
    voi_count_ += B;
  }
  adding_.seconds_gae += Lap(lap);

  batch->size += B;
  batch->obs.insert(batch->obs.end(), q.obs.begin(), q.obs.end());
  batch->critic_inputs.insert(batch->critic_inputs.end(), inputs.begin(), inputs.begin() + B * critic_dim);
  batch->actions.insert(batch->actions.end(), u.actions().begin(), u.actions().end());
  batch->behaviour_log_probs.insert(batch->behaviour_log_probs.end(), u.behaviour_log_probs().begin(),
                                    u.behaviour_log_probs().end());
  for (int64_t i = 0; i < B; ++i) {
    batch->advantages.push_back(adv_ext[i] + static_cast<float>(config_.intrinsic_coef) * adv_int[i] +
                                (edti ? adv_voi[i] : 0.0f));
  }
  batch->returns_ext.insert(batch->returns_ext.end(), ret_ext.begin(), ret_ext.end());
  batch->returns_int.insert(batch->returns_int.end(), ret_int.begin(), ret_int.end());
  batch->returns_voi.insert(batch->returns_voi.end(), ret_voi.begin(), ret_voi.end());
  adding_.seconds_copy += Lap(lap);
  return absl::OkStatus();
}

absl::StatusOr<IterationStats> Mappo::Train() {
  IterationStats stats = adding_;
  const double voi_reward = voi_count_ > 0 ? voi_sum_ / voi_count_ : 0.0;
  adding_ = IterationStats();
  voi_sum_ = 0;
  voi_count_ = 0;
  absl::StatusOr<PpoStats> trained = trainer_->Train(batch_);
  batch_.Clear();
  if (!trained.ok()) return trained.status();
  const PpoStats& ppo = *trained;
  stats.values = {{"policy_loss", ppo.policy_loss}, {"value_loss", ppo.value_loss},
                  {"approx_kl", ppo.approx_kl},     {"clip_fraction", ppo.clip_fraction},
                  {"behaviour_kl", ppo.behaviour_kl}, {"voi_reward", voi_reward}};
  stats.entropy = ppo.entropy;
  stats.grad_norm = ppo.grad_norm;
  stats.seconds_prepare = ppo.seconds_prepare;
  stats.seconds_forward = ppo.seconds_forward;
  stats.seconds_backward = ppo.seconds_backward;
  stats.seconds_optimizer = ppo.seconds_optimizer;
  stats.minibatches_skipped = ppo.minibatches_skipped;
  stats.skip_reason = ppo.skip_reason;
  stats.updates = int64_t{options_.ppo.epochs} * options_.ppo.minibatches - stats.minibatches_skipped;
  return stats;
}

}  // namespace imca::learner
