#ifndef IMCA_LEARNER_ALGORITHMS_MAPPO_MAPPO_H_
#define IMCA_LEARNER_ALGORITHMS_MAPPO_MAPPO_H_

#include <memory>
#include <vector>

#include "absl/status/statusor.h"
#include "common/env/env.h"
#include "common/env/featurizer.h"
#include "learner/algorithms/interface.h"
#include "learner/algorithms/mappo/mappo_options.h"
#include "learner/algorithms/mappo/ppo_trainer.h"
#include "learner/learner_config.h"

namespace imca::learner {

// MAPPO: a shared actor and a centralised critic (PpoTrainer). An
// iteration's unrolls become one batch: each unroll's values and advantages
// (GAE with the extrinsic and intrinsic heads, or one head of their sum;
// EDTI's interaction term with --edti) are computed as it arrives, while the
// actors produce the rest, and Train runs the PPO epochs over the batch.
// Featurise writes obs [T][E][n][obs_dim] and critic_inputs
// [T+1][E][n][critic_dim]. Thread safety as Algorithm.
class Mappo final : public Algorithm {
 public:
  // `scenario` must outlive it; its own settings are config.options, a
  // MappoOptions (none: the defaults). Errors: INVALID_ARGUMENT for a bad
  // config.
  static absl::StatusOr<std::unique_ptr<Mappo>> Create(const env::Scenario* scenario, const LearnerConfig& config);

  FeaturisedUnroll Featurise(v1::Unroll unroll) const override;
  // steps * n * (obs_dim + critic_dim) floats, four times (the batch; the
  // featurised unrolls it is gathered from and those waiting in the queue;
  // the minibatch gathers and activations; the trainer works on views of the
  // batch, not copies). Measured on coop_nav before unrolls were featurised
  // on push: the learner's peak grew 5.8 KB per joint step against this
  // estimate's 7.0 KB.
  int64_t IterationBytes(int64_t steps) const override;
  bool needs_influences() const override { return options_.edti; }
  absl::Status Add(const FeaturisedUnroll& unroll) override;
  absl::StatusOr<IterationStats> Train() override;
  v1::Policy ExportPolicy(int64_t version) const override { return trainer_->ExportPolicy(version); }
  absl::Status Save(const std::string& path) const override { return trainer_->Save(path); }
  absl::Status Load(const std::string& path) override { return trainer_->Load(path); }

  // Floats of the critic's input per agent sample.
  int critic_dim() const { return trainer_->critic_dim(); }

 private:
  Mappo(const env::Scenario* scenario, const LearnerConfig& config, const MappoOptions& options,
        std::unique_ptr<PpoTrainer> trainer);
  // Writes the critic inputs of every agent in `state`, [n][critic_dim]: the
  // state's encoding once, copied per agent with its id. `obs`, if not null,
  // holds the agents' observations of `state` ([n][obs_dim]), which the
  // joint-observation input reuses instead of observing again.
  void CriticInputsOf(const int32_t* state, const float* obs, float* out) const;

  const env::Scenario* scenario_;
  const LearnerConfig config_;
  const MappoOptions options_;
  const env::Featurizer featurizer_;
  std::unique_ptr<PpoTrainer> trainer_;
  PpoBatch batch_;          // The current iteration's; reused every iteration.
  IterationStats adding_;   // Add's timings and EDTI's rewards of the current iteration.
  double voi_sum_ = 0;
  int64_t voi_count_ = 0;
};

// Critic input width for `config` on `scenario` (joint observations or the
// global state, plus the agent id).
int MappoCriticDim(const env::Scenario& scenario, const LearnerConfig& config);


}  // namespace imca::learner

#endif  // IMCA_LEARNER_ALGORITHMS_MAPPO_MAPPO_H_
