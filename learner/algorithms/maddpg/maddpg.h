#ifndef IMCA_LEARNER_ALGORITHMS_MADDPG_MADDPG_H_
#define IMCA_LEARNER_ALGORITHMS_MADDPG_MADDPG_H_

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "common/env/env.h"
#include "learner/algorithms/interface.h"
#include "learner/algorithms/maddpg/maddpg_options.h"
#include "learner/learner_config.h"

namespace imca::learner {

// MADDPG for discrete actions (Lowe et al. 2017, as openai/maddpg's
// trainer/maddpg.py and its PyTorch port run it; docs/learner.md "MADDPG"):
// - actors mu_i(o_i) -> logits; acting samples softmax(logits), which is the
//   hard Gumbel-softmax sample, so actors are unchanged;
// - a centralised critic Q_i(o_1..o_n, a_1..a_n) per agent (one-hot joint
//   action; with share_parameters one critic with an agent-id input);
// - critic target y_i = r_i + gamma (1 - done) Q'_i(o', a'), a'_k a hard
//   Gumbel-softmax sample of target actor mu'_k(o'_k);
// - actor loss -Q_i(o, a_1..a_i..a_n) + policy_reg * mean(logits_i^2) with a_i
//   the straight-through hard Gumbel-softmax sample of mu_i and the others'
//   actions those of the replay (openai/maddpg);
// - Adam, per-network grad-norm clip, soft target updates (tau) after
//   every gradient step; r_i = r_ext + intrinsic_coef * r_int, so every
//   reward kind and credit mode enters as for one-head PPO.
// The replay buffer keeps compact states (not features) and featurises a
// sampled batch; it is not checkpointed: a restarted learner refills it
// (learning_starts) and goes on with its networks, optimisers and update
// ratio restored. Featurise keeps the unroll as it is.
class Maddpg final : public Algorithm {
 public:
  // `scenario` must outlive it. Errors: INVALID_ARGUMENT naming a bad
  // config field, or a replay (ReplayBytes) over config.max_batch_bytes.
  static absl::StatusOr<std::unique_ptr<Maddpg>> Create(const env::Scenario* scenario, const LearnerConfig& config);
  ~Maddpg() override;

  bool off_policy() const override { return true; }
  FeaturisedUnroll Featurise(v1::Unroll unroll) const override;
  // The queued unrolls' states and rewards (the replay is bounded by
  // buffer_transitions instead, see ReplayBytes).
  int64_t IterationBytes(int64_t steps) const override;
  // Inserts the unroll's transitions, then takes the gradient steps now due
  // (updates_per_step for every step inserted once the replay holds
  // learning_starts).
  absl::Status Add(const FeaturisedUnroll& unroll) override;
  absl::StatusOr<IterationStats> Train() override;
  // MLP_RELU (policy.<i>.*), or without shared parameters one network per
  // agent (agent<k>.policy.<i>.*, agent_networks n).
  v1::Policy ExportPolicy(int64_t version) const override;
  absl::Status Save(const std::string& path) const override;
  absl::Status Load(const std::string& path) override;

  // Bytes the full replay holds.
  int64_t ReplayBytes() const;
  int64_t replay_size() const;
  int64_t updates() const;

  // The pieces, for tests with hand-worked numbers.
  struct Transition {
    std::vector<int32_t> state, next_state;  // [K] each.
    std::vector<int32_t> actions;            // [n]
    std::vector<float> rewards;              // [n], already r_ext + c_int r_int.
    bool done = false;                       // No bootstrap.
  };
  // Inserts one transition (no updates).
  void InsertForTest(const Transition& t);
  // The critic targets y [n] of transition `index`.
  absl::StatusOr<std::vector<float>> CriticTargetsForTest(int64_t index);
  // `count` uniform replay indices from the algorithm's generator.
  std::vector<int64_t> SampleIndicesForTest(int count);
  // One gradient step on the whole replay (tests with a small one).
  absl::Status UpdateForTest();
  // Acting probabilities of every agent in `state`, [n][A].
  std::vector<float> ProbabilitiesForTest(const std::vector<int32_t>& state);

 private:
  struct Impl;
  explicit Maddpg(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};


}  // namespace imca::learner

#endif  // IMCA_LEARNER_ALGORITHMS_MADDPG_MADDPG_H_
