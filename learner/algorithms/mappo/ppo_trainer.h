#ifndef IMCA_LEARNER_ALGORITHMS_MAPPO_PPO_TRAINER_H_
#define IMCA_LEARNER_ALGORITHMS_MAPPO_PPO_TRAINER_H_

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
// What the PPO clip is measured against (docs/learner.md, "Staleness").
enum class PpoObjective {
  // ratio = pi / behaviour, clipped: the textbook surrogate, with the actor's
  // recorded log-probabilities as the old policy.
  kBehaviour,
  // Decoupled PPO (Hilton et al. 2021, "Batch size-invariance for policy
  // optimization"): the clip is measured against a proximal policy, the
  // learner's own policy at the start of the iteration (recomputed on the
  // batch), and the behaviour policy enters only as the importance weight
  // pi_prox / behaviour:  -mean(w * min(r A, clip(r, 1 -+ eps) A)),
  // r = pi / pi_prox, w = pi_prox / behaviour.
  kDecoupled,
};

// How the critic's targets are normalised (one normaliser per value head;
// the critic predicts normalised returns, and Values denormalises them).
enum class ValueNorm {
  // Running mean and variance of every return seen, merged a whole
  // iteration's batch at a time before it trains (Chan et al.), std >= 0.01.
  kBatch,
  // marlbenchmark/on-policy's ValueNorm: debiased exponential moving averages
  // of the mean and the mean square (beta 0.99999), updated with each
  // minibatch's returns just before its loss (every epoch), variance >= 0.01.
  kEma,
};

// "behaviour" / "decoupled".
std::string PpoObjectiveName(PpoObjective objective);
std::vector<std::string> PpoObjectiveNames();
// Errors: INVALID_ARGUMENT naming the accepted values.
absl::StatusOr<PpoObjective> ParsePpoObjective(const std::string& name);

struct PpoConfig {
  int hidden = 64;             // Width of the two hidden layers (actor and critic).
  double learning_rate = 5e-4;
  double adam_eps = 1e-5;
  double clip = 0.2;           // PPO ratio clip.
  double value_coef = 0.5;
  double entropy_coef = 0.01;
  double max_grad_norm = 0.5;
  int epochs = 4;
  int minibatches = 4;
  uint64_t seed = 1;
  int threads = 1;             // LibTorch intra-op threads (of each pass below).
  // Each minibatch's critic forward and backward pass runs on a second thread
  // while the actor's run on the training thread. Actor and critic share no
  // parameters, so the update is the same as one after the other; false: one
  // thread does both.
  bool concurrent_critic = true;
  PpoObjective objective = PpoObjective::kBehaviour;
  // LayerNorm after every hidden activation, in actor and critic (as every
  // marlbenchmark/on-policy MLP), and with input_norm on the input too (its
  // feature normalisation).
  bool layer_norm = false;
  bool input_norm = true;  // With layer_norm only.
  ValueNorm value_norm = ValueNorm::kBatch;
  // Two Adam optimisers (actor, critic), each with its own grad-norm clip at
  // max_grad_norm, as on-policy's R_MAPPO; false: one over both, one clip.
  // Which is better depends on the task (docs/benchmarks.md); ./imca train
  // picks per scenario.
  bool separate_optimizers = false;
  // Critic outputs: 2 = extrinsic and intrinsic heads (returns_int trained),
  // 1 = one head on returns_ext (the learner folds the bonus into the reward),
  // 3 = those two and EDTI's interaction head (returns_voi trained).
  int value_heads = 2;
  double hidden_gain = 1.4142135623730951;  // Orthogonal init gain of hidden layers (sqrt 2).
  // > 0: PPO-style value clipping, the loss is the max of the plain and the
  // clipped error, predictions clipped to +-value_clip around the critic's
  // (normalised) values at the start of the iteration. 0: off.
  double value_clip = 0;
  // > 0: Huber value loss with this delta (on normalised targets); 0: MSE.
  double huber_delta = 0;
};

// One training batch of B per-agent samples, row-major.
struct PpoBatch {
  int64_t size = 0;                       // B
  std::vector<float> obs;                 // [B][obs_dim], policy input.
  std::vector<float> critic_inputs;       // [B][critic_dim], critic input.
  std::vector<int32_t> actions;           // [B]
  std::vector<float> behaviour_log_probs; // [B], recorded by the actor.
  std::vector<float> advantages;          // [B], A_ext + c_int * A_int (+ A_voi with EDTI), unnormalised.
  std::vector<float> returns_ext;         // [B], value targets (unnormalised).
  std::vector<float> returns_int;         // [B]
  std::vector<float> returns_voi;         // [B], value_heads 3 only (EDTI's value of interaction).

  // Empties the batch but keeps the vectors' memory, so that a batch reused
  // every iteration allocates (and page-faults) nothing.
  void Clear() {
    size = 0;
    for (auto* v : {&obs, &critic_inputs, &behaviour_log_probs, &advantages, &returns_ext, &returns_int,
                    &returns_voi}) {
      v->clear();
    }
    actions.clear();
  }
};

struct PpoStats {
  double policy_loss = 0;
  double value_loss = 0;
  double entropy = 0;
  // Ratios are to the policy the clip is measured against: the behaviour
  // policy, or the proximal one with PpoObjective::kDecoupled.
  double approx_kl = 0;      // Mean of (ratio - 1) - log ratio, last epoch.
  double clip_fraction = 0;  // Share of samples whose ratio was clipped.
  // Mean of (w - 1) - log w, w = pi_start / behaviour, pi_start the policy at
  // the start of Train: how stale the batch was (0 when acted on-policy).
  // Over the whole batch with kDecoupled, else over the first minibatch.
  double behaviour_kl = 0;
  double grad_norm = 0;      // Before clipping, mean over minibatches.
  // Wall seconds of Train's phases: the batch copied into tensors with the
  // advantage and target normalisation and the start-of-iteration forward
  // passes; then summed over minibatches: forward passes and losses,
  // backward pass, gradient clipping and optimiser steps.
  double seconds_prepare = 0;
  double seconds_forward = 0;
  double seconds_backward = 0;
  double seconds_optimizer = 0;
  // Minibatches that took no step because their loss or gradient was not
  // finite, and why the first of them failed.
  int64_t minibatches_skipped = 0;
  std::string skip_reason;
};

// Not thread-safe: the learner's training thread owns it.
class PpoTrainer {
 public:
  // Builds actor (obs_dim -> hidden -> hidden -> num_actions, tanh,
  // orthogonal init, last layer gain 0.01) and critic (critic_dim -> hidden ->
  // hidden -> value_heads, orthogonal init, last layer gain 1), optionally
  // with LayerNorms, and one Adam optimiser over both or one each.
  // Errors: INVALID_ARGUMENT for non-positive sizes or bad config values.
  static absl::StatusOr<std::unique_ptr<PpoTrainer>> Create(const PpoConfig& config, int obs_dim,
                                                            int critic_dim, int num_actions);
  ~PpoTrainer();

  // Denormalised value predictions for critic inputs [batch][critic_dim];
  // with one value head, v_int is all zeros; v_voi (may be null) gets the
  // interaction head's, zeros without it.
  // Errors: INTERNAL if LibTorch throws.
  absl::Status Values(const float* critic_inputs, int64_t batch, float* v_ext, float* v_int,
                      float* v_voi = nullptr);

  // Updates the return normalisers with the batch's returns (per batch or
  // per minibatch: PpoConfig::value_norm), normalises the
  // advantages (mean 0, std 1), then runs `epochs` passes over `minibatches`
  // shuffled minibatches: clipped surrogate (PpoConfig::objective), value
  // loss on normalised targets, entropy bonus, grad-norm clipping. With one
  // value head, returns_int is ignored; returns_voi is read with three.
  // A minibatch whose loss or gradient is not finite takes no step and is
  // counted in PpoStats::minibatches_skipped; the log-ratios are bounded
  // (to +-10 before the exp), so no recorded log-probability makes them
  // infinite. Errors, each with the trainer unchanged: INVALID_ARGUMENT if
  // the batch's vectors do not match `size` or an element is out of range or
  // not finite; INTERNAL if LibTorch throws.
  absl::StatusOr<PpoStats> Train(const PpoBatch& batch);

  // The actor as named tensors, see learner_service.proto: architecture
  // MLP_TANH ("policy.<i>.weight"/"policy.<i>.bias"), or with layer_norm
  // MLP_TANH_LAYERNORM (plus "policy.<i>.norm.*", and "policy.input_norm.*"
  // with input_norm).
  v1::Policy ExportPolicy(int64_t version) const;

  // Writes / reads actor, critic, optimiser state and return normalisers.
  // Errors: INTERNAL on I/O failure; Load: INVALID_ARGUMENT if the file's
  // shapes or architecture (layer_norm and input_norm, value_heads,
  // separate_optimizers, value_norm) do not match this trainer (a checkpoint
  // without them is the original architecture: no layer norm, two heads, one
  // optimiser, batch normalisers).
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

#endif  // IMCA_LEARNER_ALGORITHMS_MAPPO_PPO_TRAINER_H_
