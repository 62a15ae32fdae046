#include "common/protocol/acting_policy.h"

#include <utility>

namespace imca {

absl::StatusOr<ActingPolicy> ActingPolicy::FromProto(const v1::Policy& policy, const env::Scenario& scenario) {
  ActingPolicy acting(scenario);
  if (policy.architecture() == v1::Policy::TABULAR_Q) {
    absl::StatusOr<PolicyTable> table = PolicyTable::FromProto(policy, scenario);
    if (!table.ok()) return table.status();
    acting.table_ = *std::move(table);
    return acting;
  }
  absl::StatusOr<PolicyMlp> mlp = PolicyMlp::FromProto(policy);
  if (!mlp.ok()) return mlp.status();
  if (absl::Status fits = mlp->Fits(acting.featurizer_.obs_dim(), scenario.num_actions(), scenario.num_agents());
      !fits.ok()) {
    return fits;
  }
  acting.mlp_ = *std::move(mlp);
  return acting;
}

void ActingPolicy::Probabilities(const int32_t* states, int num_envs, bool evaluation, float* probs) {
  if (table_) {
    table_->Probabilities(states, num_envs, evaluation, probs);
    return;
  }
  const int obs_dim = featurizer_.obs_dim();
  // Grown only: actors alternate training and evaluation batches.
  const size_t size = static_cast<size_t>(num_envs) * n_ * obs_dim;
  if (obs_.size() < size) obs_.resize(size);
  for (int e = 0; e < num_envs; ++e) {
    const int32_t* state = states + static_cast<size_t>(e) * state_size_;
    for (int a = 0; a < n_; ++a) featurizer_.Observe(state, a, &obs_[static_cast<size_t>(e * n_ + a) * obs_dim]);
  }
  mlp_->Probabilities(obs_.data(), num_envs * n_, probs);
}

}  // namespace imca
