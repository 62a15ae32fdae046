#ifndef IMCA_LEARNER_ALGORITHMS_CMAE_CMAE_H_
#define IMCA_LEARNER_ALGORITHMS_CMAE_CMAE_H_

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "common/env/env.h"
#include "common/env/joint_state.h"
#include "learner/algorithms/cmae/cmae_options.h"
#include "learner/algorithms/cmae/cmae_parts.h"
#include "learner/algorithms/interface.h"
#include "learner/learner_config.h"

namespace imca::learner {

// CMAE (Liu et al., ICML 2021) as its released gridworld code runs it
// (CMAE's q_learner.py, main.py with --tree_subspace
// --stochastic_select_subspace --mixed_explore; docs/baselines.md "CMAE"): tabular
// Q-learning over joint states (common/env/joint_state.h), one exploration and one
// exploitation table per agent, acting greedily on their mix.
//
// Each step of an unroll (in time order) joins its (actor, env) episode;
// an episode enters when it ends (so that it is one run of slots with any
// number of environments; with one, as the code inserts and counts each
// step): each step is counted in every tracked restricted space
// (cmae::Subspaces) and in the joint count, and stored in the replay and,
// while its pair was seen fewer than insert_threshold times, the goal
// replay. Then, at that episode end: a goal (state, joint action) of least
// restricted count among goal_samples states of the goal replay; each
// agent's exploitation table fitted on a batch of the replay led by the
// first successful episode in it; each agent's exploration table reset and
// fitted on the replay's episode into the goal state, with reward 1 only
// for the goal pair and a terminal goal // transition after it. The extrinsic reward is the team's (the mean over
// agents); the reward server's intrinsic rewards are not used. Training
// happens as unrolls are added (off-policy); Train only reports.
//
// The exported policy (TABULAR_Q) holds the exploration tables, the
// exploitation tables' nonzero rows and the weight
// min(1, episodes / total_episodes) of the exploitation side; evaluation
// environments act on the exploitation tables alone (the code's eval).
// Save writes the whole state (tables, counters, replays, open episodes,
// generator): a resumed learner goes on exactly.
class Cmae final : public Algorithm {
 public:
  // `scenario` must outlive it. Errors: INVALID_ARGUMENT naming a bad
  // cmae field, a scenario with more than 5 actions or 32 variables, or a
  // joint state too large to index (env::JointStateSpace) or whose tables
  // could outgrow max_table_mb (TableBytes).
  static absl::StatusOr<std::unique_ptr<Cmae>> Create(const env::Scenario* scenario, const LearnerConfig& config);
  ~Cmae() override;

  bool off_policy() const override { return true; }
  FeaturisedUnroll Featurise(v1::Unroll unroll) const override;
  int64_t IterationBytes(int64_t steps) const override;
  absl::Status Add(const FeaturisedUnroll& unroll) override;
  absl::StatusOr<IterationStats> Train() override;
  v1::Policy ExportPolicy(int64_t version) const override;
  absl::Status Save(const std::string& path) const override;
  absl::Status Load(const std::string& path) override;

  // Bytes the tables could reach: the replays, and per joint state that
  // could be visited (the fewer of the joint states and budget_steps; all
  // joint states without a budget) a row of each Q-table, the joint
  // counts and a count in each tracked restricted space.
  static double TableBytes(const env::JointStateSpace& space, const LearnerConfig& config);

  const env::JointStateSpace& space() const;
  int64_t episodes() const;
  double exploit_weight() const;
  const cmae::QTable& explore(int agent) const;
  const cmae::QTable& exploit(int agent) const;
  const cmae::Subspaces& subspaces() const;
  const cmae::Replay& replay() const;
  // The goal of the latest episode end (joint state, joint action), -1 before.
  std::pair<int64_t, int64_t> goal() const;

 private:
  struct Impl;
  explicit Cmae(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};


}  // namespace imca::learner

#endif  // IMCA_LEARNER_ALGORITHMS_CMAE_CMAE_H_
