#ifndef IMCA_LEARNER_ALGORITHMS_CMAE_CMAE_OPTIONS_H_
#define IMCA_LEARNER_ALGORITHMS_CMAE_CMAE_OPTIONS_H_

#include <cstdint>

namespace imca::learner {

// CMAE's own settings (LearnerConfig::options of a learner with --algo cmae),
// as its released gridworld code runs it (cmae.h, docs/baselines.md "CMAE"):
// its main.py's defaults and the flags its scripts pass (--tree_subspace
// --stochastic_select_subspace --mixed_explore); its discount is this
// struct's, not LearnerConfig::gamma.
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

// CMAE's settings (common/base/settings.h): type, flag, field of CmaeConfig, help.
#define IMCA_CMAE_SETTINGS(X)                                                                                       \
  X(double, cmae_gamma, gamma, "cmae: discount of its Q-tables")                                                    \
  X(double, cmae_explore_lr, explore_lr, "cmae: the exploration tables' learning rate (alpha1)")                    \
  X(double, cmae_exploit_lr, exploit_lr, "cmae: the exploitation tables' learning rate (alpha2)")                   \
  X(int64_t, cmae_replay, replay, "cmae: replay capacity in joint transitions")                                     \
  X(int64_t, cmae_episodes, total_episodes,                                                                         \
    "cmae: episodes over which acting moves from the exploration to the exploitation tables")                      \
  X(int, cmae_goal_samples, goal_samples, "cmae: replay states each goal is chosen among")                          \
  X(int, cmae_batch, batch, "cmae: transitions of each exploitation fit")                                           \
  X(int, cmae_entropy_every, entropy_every, "cmae: goals between choices of the restricted space")                  \
  X(double, cmae_recip_t, recip_t, "cmae: reciprocal temperature of that choice")                                   \
  X(int, cmae_tracked, tracked, "cmae: restricted spaces weighed at each choice")                                   \
  X(int64_t, cmae_insert_threshold, insert_threshold,                                                               \
    "cmae: a (state, joint action) seen this often enters the goal replay no more")                                \
  X(int64_t, cmae_max_table_mb, max_table_mb, "cmae: refuse a scenario whose tables could outgrow this many MB")

}  // namespace imca::learner

#endif  // IMCA_LEARNER_ALGORITHMS_CMAE_CMAE_OPTIONS_H_
