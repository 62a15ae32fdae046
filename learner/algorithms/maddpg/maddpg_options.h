#ifndef IMCA_LEARNER_ALGORITHMS_MADDPG_MADDPG_OPTIONS_H_
#define IMCA_LEARNER_ALGORITHMS_MADDPG_MADDPG_OPTIONS_H_

#include <cstdint>

namespace imca::learner {

// MADDPG's own settings (LearnerConfig::options of a learner with --algo
// maddpg; maddpg.h, docs/learner.md "MADDPG"): the reference
// implementations' defaults (docs/baselines.md) where our episodes allow
// them. Its discount is LearnerConfig::gamma.
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

// MADDPG's settings (common/base/settings.h): type, flag, field of MaddpgConfig, help.
#define IMCA_MADDPG_SETTINGS(X)                                                                                     \
  X(int, maddpg_hidden, hidden, "maddpg: hidden layer width (actor and critic)")                                   \
  X(double, maddpg_actor_lr, actor_lr, "maddpg: actor Adam learning rate")                                          \
  X(double, maddpg_critic_lr, critic_lr, "maddpg: critic Adam learning rate")                                       \
  X(double, maddpg_tau, tau, "maddpg: soft target update rate per gradient step")                                   \
  X(double, maddpg_max_grad_norm, max_grad_norm, "maddpg: grad-norm clip per network")                              \
  X(double, maddpg_policy_reg, policy_reg, "maddpg: weight of mean(logits^2) in the actor loss")                    \
  X(int, maddpg_batch, batch_size, "maddpg: transitions per gradient step")                                         \
  X(int64_t, maddpg_buffer, buffer_transitions, "maddpg: replay capacity in joint transitions")                     \
  X(int64_t, maddpg_learning_starts, learning_starts, "maddpg: transitions in the replay before the first update")  \
  X(double, updates_per_step, updates_per_step,                                                                     \
    "maddpg: gradient steps per joint env step; the learner takes no more data than this allows, so actors are "    \
    "slowed to it")                                                                                                 \
  X(bool, maddpg_share, share_parameters,                                                                           \
    "maddpg: one actor and one critic (agent id in the input) for all agents; false: one of each per agent")

}  // namespace imca::learner

#endif  // IMCA_LEARNER_ALGORITHMS_MADDPG_MADDPG_OPTIONS_H_
