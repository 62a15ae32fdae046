#include "common/protocol/policy_table.h"

#include <cmath>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"

namespace imca {

absl::StatusOr<PolicyTable::Rows> PolicyTable::ReadTable(const v1::QTable& table, const char* name,
                                                         int64_t row_size, int64_t joint_states) {
  if (static_cast<int64_t>(table.values_size()) != table.states_size() * row_size) {
    return absl::InvalidArgumentError(absl::StrCat("tabular.", name, ": ", table.values_size(), " values for ",
                                                   table.states_size(), " states of ", row_size, " each"));
  }
  Rows rows;
  rows.reserve(table.states_size());
  for (int i = 0; i < table.states_size(); ++i) {
    const int64_t state = table.states(i);
    if (state < 0 || state >= joint_states || (i > 0 && state <= table.states(i - 1))) {
      return absl::InvalidArgumentError(absl::StrCat("tabular.", name, ".states[", i, "] = ", state,
                                                     ": not ascending within [0, ", joint_states, ")"));
    }
    rows.emplace(state, i);
  }
  for (double v : table.values()) {
    if (!std::isfinite(v)) return absl::InvalidArgumentError(absl::StrCat("tabular.", name, ": a value is not finite"));
  }
  return rows;
}

absl::StatusOr<PolicyTable> PolicyTable::FromProto(const v1::Policy& policy, const env::Scenario& scenario) {
  if (policy.architecture() != v1::Policy::TABULAR_Q) {
    return absl::InvalidArgumentError(
        absl::StrCat("architecture ", v1::Policy::Architecture_Name(policy.architecture()), " is not TABULAR_Q"));
  }
  IMCA_ASSIGN_OR_RETURN(env::JointStateSpace space, env::JointStateSpace::Create(scenario));
  const v1::TabularPolicy& t = policy.tabular();
  if (t.num_agents() != scenario.num_agents()) {
    return absl::InvalidArgumentError(
        absl::StrCat("tabular.num_agents ", t.num_agents(), " != the scenario's ", scenario.num_agents()));
  }
  if (policy.num_actions() != scenario.num_actions()) {
    return absl::InvalidArgumentError(
        absl::StrCat("num_actions ", policy.num_actions(), " != the scenario's ", scenario.num_actions()));
  }
  if (t.joint_states() != space.size()) {
    return absl::InvalidArgumentError(absl::StrCat("tabular.joint_states ", t.joint_states(),
                                                   " != the scenario's ", space.size()));
  }
  if (!(t.exploit_weight() >= 0 && t.exploit_weight() <= 1)) {
    return absl::InvalidArgumentError(absl::StrCat("tabular.exploit_weight ", t.exploit_weight(), " not in [0, 1]"));
  }
  const int64_t row_size = int64_t{scenario.num_agents()} * scenario.num_actions();
  PolicyTable table(std::move(space), scenario.state_size());
  IMCA_ASSIGN_OR_RETURN(table.explore_rows_, ReadTable(t.explore(), "explore", row_size, t.joint_states()));
  IMCA_ASSIGN_OR_RETURN(table.exploit_rows_, ReadTable(t.exploit(), "exploit", row_size, t.joint_states()));
  table.explore_.assign(t.explore().values().begin(), t.explore().values().end());
  table.exploit_.assign(t.exploit().values().begin(), t.exploit().values().end());
  table.version_ = policy.version();
  table.weight_ = t.exploit_weight();
  return table;
}

void PolicyTable::Probabilities(const int32_t* states, int num_envs, bool evaluation, float* probs) const {
  const int n = space_.num_agents(), A = space_.num_actions();
  for (int e = 0; e < num_envs; ++e) {
    const int32_t* state = states + static_cast<size_t>(e) * state_size_;
    const int64_t index = space_.Index(state);
    const auto explore = explore_rows_.find(index);
    const auto exploit = exploit_rows_.find(index);
    for (int a = 0; a < n; ++a) {
      double mixed[env::kStay + 1];
      double best = 0;
      for (int u = 0; u < A; ++u) {
        const double qe = explore == explore_rows_.end() ? 0 : explore_[(explore->second * n + a) * A + u];
        const double qx = exploit == exploit_rows_.end() ? 0 : exploit_[(exploit->second * n + a) * A + u];
        mixed[u] = evaluation ? qx : (1 - weight_) * qe + weight_ * qx;
        if (u == 0 || mixed[u] > best) best = mixed[u];
      }
      int ties = 0;
      for (int u = 0; u < A; ++u) ties += mixed[u] == best;
      float* p = probs + (static_cast<size_t>(e) * n + a) * A;
      for (int u = 0; u < A; ++u) p[u] = mixed[u] == best ? 1.0f / static_cast<float>(ties) : 0.0f;
    }
  }
}

}  // namespace imca
