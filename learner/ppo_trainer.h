#ifndef IMCA_LEARNER_PPO_TRAINER_H_
#define IMCA_LEARNER_PPO_TRAINER_H_

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "imca/v1/learner_service.pb.h"

namespace imca::learner {

// Multi-agent PPO (MAPPO) with a shared actor and a centralised critic with
// two heads (extrinsic and intrinsic value). LibTorch stays behind this
// header (pimpl) so that gRPC and test code never compile torch headers.
struct PpoConfig {
  int hidden = 64;             // Width of the two hidden layers (actor and critic).
  double learning_rate = 3e-4;
  double adam_eps = 1e-5;
  double clip = 0.2;           // PPO ratio clip.
  double value_coef = 0.5;
  double entropy_coef = 0.01;
  double max_grad_norm = 0.5;
  int epochs = 4;
  int minibatches = 4;
  uint64_t seed = 1;
  int threads = 1;             // LibTorch intra-op threads.
};

// One training batch of B per-agent samples, row-major.
struct PpoBatch {
  int64_t size = 0;                       // B
  std::vector<float> obs;                 // [B][obs_dim], policy input.
  std::vector<float> critic_inputs;       // [B][critic_dim], critic input.
  std::vector<int32_t> actions;           // [B]
  std::vector<float> behaviour_log_probs; // [B], recorded by the actor.
  std::vector<float> advantages;          // [B], A_ext + c_int * A_int (unnormalised).
  std::vector<float> returns_ext;         // [B], value targets (unnormalised).
  std::vector<float> returns_int;         // [B]
};

struct PpoStats {
  double policy_loss = 0;
  double value_loss = 0;
  double entropy = 0;
  double approx_kl = 0;      // Mean of (ratio - 1) - log ratio, last epoch.
  double clip_fraction = 0;  // Share of samples whose ratio was clipped.
  double grad_norm = 0;      // Before clipping, mean over minibatches.
};

// Not thread-safe: the learner's training thread owns it.
class PpoTrainer {
 public:
  // Builds actor (obs_dim -> hidden -> hidden -> num_actions, tanh,
  // orthogonal init, last layer gain 0.01) and critic (critic_dim -> hidden ->
  // hidden -> 2, orthogonal init) and an Adam optimiser over both.
  // Errors: INVALID_ARGUMENT for non-positive sizes or bad config values.
  static absl::StatusOr<std::unique_ptr<PpoTrainer>> Create(const PpoConfig& config, int obs_dim,
                                                            int critic_dim, int num_actions);
  ~PpoTrainer();

  // Denormalised value predictions for critic inputs [batch][critic_dim].
  void Values(const float* critic_inputs, int64_t batch, float* v_ext, float* v_int);

  // Updates the return normalisers with the batch's returns, normalises the
  // advantages (mean 0, std 1), then runs `epochs` passes over `minibatches`
  // shuffled minibatches: clipped surrogate on exp(log pi - behaviour_log_probs),
  // value loss on normalised targets, entropy bonus, global grad-norm clipping.
  // Errors: INVALID_ARGUMENT if the batch's vectors do not match `size`;
  // INTERNAL if LibTorch throws or a loss becomes non-finite (weights are
  // left as before that minibatch).
  absl::StatusOr<PpoStats> Train(const PpoBatch& batch);

  // The actor as named tensors ("policy.<i>.weight"/"policy.<i>.bias",
  // architecture "mlp_tanh"), see learner_service.proto.
  v1::Policy ExportPolicy(int64_t version) const;

  // Writes / reads actor, critic, optimiser state and return normalisers.
  // Errors: INTERNAL on I/O failure; Load: INVALID_ARGUMENT if the file's
  // shapes do not match this trainer.
  absl::Status Save(const std::string& path) const;
  absl::Status Load(const std::string& path);

  int obs_dim() const;
  int critic_dim() const;
  int num_actions() const;

 private:
  struct Impl;
  explicit PpoTrainer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace imca::learner

#endif  // IMCA_LEARNER_PPO_TRAINER_H_
