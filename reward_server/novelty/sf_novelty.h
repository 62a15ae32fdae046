#ifndef IMCA_REWARD_SERVER_NOVELTY_SF_NOVELTY_H_
#define IMCA_REWARD_SERVER_NOVELTY_SF_NOVELTY_H_

#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "common/env/env.h"
#include "reward_server/credit.h"
#include "reward_server/novelty/learned_novelty.h"

namespace imca::reward {

struct SfConfig {
  std::vector<int> hidden = {128, 128};  // Hidden widths of phi and psi; {} = one linear layer.
  int features = 32;                     // Size of phi and psi.
  double gamma = 0.95;                   // Successor-feature discount gamma_sf.
  double learning_rate = 1e-3;           // Adam, psi only.
  int target_update = 20;                // Requests between copies of psi into its target.
};

// SF's settings (common/base/settings.h): type, flag, field of SfConfig, help.
#define IMCA_SF_SETTINGS(X)                                          \
  X(double, sf_gamma, gamma, "sf: successor-feature discount")      \
  X(double, sf_lr, learning_rate, "sf: Adam learning rate of psi")

// Successor-feature control (paper eq. 7, 11-13; docs/credit.md), for CreditScorer:
//   phi: a fixed random network of the joint state (JointInputEncoder, agent
//   order); psi trained by TD, psi(S_t) -> phi(S_t) + gamma psi'(S_{t+1})
//   (psi' = target copy; 0 after termination);
//   joint: ||psi(S_{t+1}) - psi(S_t)||^2 (R_i = beta times it).
//   imca contributions: d^a = ||psi(S_t with only agent a moved to s^a_{t+1})
//   - psi(S_t)||^2 with scale 1 / sqrt(N_ep(s^a)), so r_i^a = R_i p^a /
//   sqrt(N_ep(s^a)), where N_ep counts agent a's visits to the cell it
//   reached, in this episode, this one included (keyed by actor, episode id,
//   agent and cell).
//   local (independent): a second SF over each agent's own cell.
// A request is scored with psi as it was before it, then psi takes one Adam
// step on the request's transitions. Not thread-safe (Novelty).
class SfNovelty final : public LearnedNovelty {
 public:
  // Errors: INVALID_ARGUMENT for bad config values.
  static absl::StatusOr<std::unique_ptr<SfNovelty>> Create(const env::Scenario& scenario,
                                                           const ScorerConfig& config, const SfConfig& sf);
  ~SfNovelty() override;

  void FillStats(v1::RewardStats* stats) const override;
  // Models only: episodic visit counts are transient and start afresh.
  absl::Status Load(const std::string& path) override;

  // Tests: set layer `layer` of "phi" or "psi" (joint model; "local_phi",
  // "local_psi" for independent credit; the target copy follows psi).
  absl::Status SetLinearForTest(const std::string& net, int layer, const std::vector<float>& weight,
                                const std::vector<float>& bias);
  // Tests: phi and psi of one state of the joint model, `features` floats each.
  std::vector<float> PhiForTest(const int32_t* state) const;
  std::vector<float> PsiForTest(const int32_t* state) const;

 private:
  void ComputeJoint(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out,
                    Deferred* deferred) override;
  void ComputeLocal(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out,
                    Deferred* deferred) override;
  void EndRequest(bool dry_run) override;
  absl::StatusOr<std::string> Serialize() const override;

  struct Impl;
  SfNovelty(std::unique_ptr<Impl> impl, NoveltyReads reads);
  std::unique_ptr<Impl> impl_;
};

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_NOVELTY_SF_NOVELTY_H_
