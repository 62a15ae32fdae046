#ifndef IMCA_LEARNER_ALGORITHMS_MAPPO_MAPPO_OPTIONS_H_
#define IMCA_LEARNER_ALGORITHMS_MAPPO_MAPPO_OPTIONS_H_

#include <string>
#include <vector>

#include "absl/strings/string_view.h"
#include "learner/algorithms/mappo/gae.h"
#include "learner/algorithms/mappo/ppo_trainer.h"

namespace imca::learner {

// What MAPPO's centralised critic sees besides the agent-id one-hot.
enum class CriticInput {
  kState,     // The global state encoding (featurizer global_dim).
  kJointObs,  // All agents' observations concatenated in agent order (n * obs_dim),
              // on-policy's MAPPO "share_obs".
};

// "state" / "joint_obs" (the flag's spelling; common/base/settings.h).
std::vector<std::string> SettingChoices(CriticInput);
bool AbslParseFlag(absl::string_view text, CriticInput* input, std::string* error);
std::string AbslUnparseFlag(CriticInput input);

// "batch" / "ema" (common/base/settings.h).
std::vector<std::string> SettingChoices(ValueNorm);
bool AbslParseFlag(absl::string_view text, ValueNorm* norm, std::string* error);
std::string AbslUnparseFlag(ValueNorm norm);

// PpoObjective's flag spelling, PpoObjectiveName's (common/base/settings.h).
std::vector<std::string> SettingChoices(PpoObjective);
bool AbslParseFlag(absl::string_view text, PpoObjective* objective, std::string* error);
std::string AbslUnparseFlag(PpoObjective objective);

// MAPPO's own settings (LearnerConfig::options of a learner with --algo
// mappo): the PPO trainer's, the critic's input and EDTI's value of
// interaction.
struct MappoOptions {
  PpoConfig ppo;  // Its seed and threads are LearnerConfig's.
  CriticInput critic_input = CriticInput::kState;
  // EDTI (docs/baselines.md): each agent's advantage gains that of EDTI's
  // value of interaction (EdtiInteractionRewards, gae.h, from the unroll's
  // influences and the critic's values of the influenced agents), learned by
  // a third value head (ppo.value_heads must be 3). Push refuses unrolls
  // without influences (INVALID_ARGUMENT naming unroll.influences).
  bool edti = false;
  EdtiCoefficients edti_coefficients;
};

// MAPPO's settings (common/base/settings.h): type, flag, field of MappoOptions, help.
#define IMCA_MAPPO_SETTINGS(X)                                                                                      \
  X(int, hidden, ppo.hidden, "hidden layer width")                                                                  \
  X(double, lr, ppo.learning_rate, "Adam learning rate")                                                            \
  X(bool, separate_optimizers, ppo.separate_optimizers,                                                             \
    "one Adam (and grad-norm clip) for the actor, one for the critic; false: one over both")                        \
  X(int, epochs, ppo.epochs, "PPO epochs per iteration")                                                            \
  X(int, minibatches, ppo.minibatches, "PPO minibatches per epoch")                                                 \
  X(double, entropy_coef, ppo.entropy_coef, "entropy bonus coefficient")                                            \
  X(double, clip, ppo.clip, "PPO ratio clip")                                                                       \
  X(double, value_coef, ppo.value_coef, "weight of the value loss")                                                 \
  X(double, max_grad_norm, ppo.max_grad_norm, "gradient-norm clip (per optimiser)")                                 \
  X(::imca::learner::PpoObjective, objective, ppo.objective,                                                        \
    "what the PPO clip is measured against: behaviour (the actor's recorded policy) or decoupled (a proximal "      \
    "policy recomputed by the learner; behaviour only as importance weight)")                                       \
  X(bool, layer_norm, ppo.layer_norm,                                                                               \
    "LayerNorm after every hidden layer, and with --input_norm on the input (actor and critic)")                    \
  X(bool, input_norm, ppo.input_norm,                                                                               \
    "with --layer_norm, a LayerNorm on the input too; false: after the hidden layers only (on-policy's MLP without " \
    "feature normalisation)")                                                                                       \
  X(int, value_heads, ppo.value_heads,                                                                              \
    "2: extrinsic and intrinsic value heads; 1: one head on extrinsic + intrinsic_coef * intrinsic (3: with "       \
    "--edti)")                                                                                                      \
  X(double, hidden_gain, ppo.hidden_gain, "orthogonal init gain of the hidden layers")                              \
  X(double, value_clip, ppo.value_clip,                                                                             \
    "clip value predictions to this distance from the iteration's start (normalised; 0: off)")                      \
  X(double, huber_delta, ppo.huber_delta, "Huber value loss delta (0: MSE)")                                        \
  X(::imca::learner::ValueNorm, value_norm, ppo.value_norm,                                                         \
    "the critic's return normalisers: batch (running moments of every return, merged per iteration) or ema "        \
    "(on-policy's ValueNorm: debiased moving averages updated per minibatch)")                                      \
  X(bool, concurrent_critic, ppo.concurrent_critic,                                                                 \
    "run each minibatch's critic pass on a second thread, concurrently with the actor's (same result)")             \
  X(::imca::learner::CriticInput, critic_input, critic_input,                                                       \
    "the centralised critic's input besides the agent id: state (global state) or joint_obs (all agents' "          \
    "observations)")                                                                                                \
  X(bool, edti, edti,                                                                                               \
    "EDTI's value of interaction from the unrolls' influences (reward server --reward edti); the critic gets a "    \
    "third head (--value_heads is then 3); docs/baselines.md")                                                      \
  X(float, edti_tv, edti_coefficients.tv, "edti: coefficient of the transition term (EDTI's gamma_coor_tv)")        \
  X(float, edti_tv_ext, edti_coefficients.tv_ext, "edti: weight of the partner's extrinsic value (gamma_coor_tv_e)") \
  X(float, edti_tv_int, edti_coefficients.tv_int, "edti: weight of the partner's curiosity value (gamma_coor_tv_c)") \
  X(float, edti_partner, edti_coefficients.partner, "edti: coefficient of the partner-reward term (gamma_coor_r)")  \
  X(float, edti_partner_ext, edti_coefficients.partner_ext,                                                         \
    "edti: weight of the partner's extrinsic reward (gamma_coor_r_e)")                                              \
  X(float, edti_partner_int, edti_coefficients.partner_int,                                                         \
    "edti: weight of the partner's curiosity reward (gamma_coor_r_c)")

}  // namespace imca::learner

#endif  // IMCA_LEARNER_ALGORITHMS_MAPPO_MAPPO_OPTIONS_H_
