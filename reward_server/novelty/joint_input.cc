#include "reward_server/novelty/joint_input.h"

#include <algorithm>

namespace imca::reward {

JointInputEncoder::JointInputEncoder(const env::Scenario& scenario)
    : n_(scenario.num_agents()),
      m_(scenario.num_npcs()),
      num_actions_(scenario.num_actions()),
      width_(scenario.map().width()),
      height_(scenario.map().height()),
      object_bits_(scenario.num_object_bits()),
      block_(height_ + width_),
      state_dim_((n_ + m_) * block_ + object_bits_) {}

void JointInputEncoder::EncodeState(const int32_t* state, const int* order, float* out) const {
  std::fill(out, out + state_dim_, 0.0f);
  for (int i = 0; i < n_ + m_; ++i) {
    const int32_t cell = i < n_ ? state[env::AgentIndex(order[i])] : state[1 + i];
    out[i * block_ + cell / width_] = 1.0f;
    out[i * block_ + height_ + cell % width_] = 1.0f;
  }
  const uint32_t z = static_cast<uint32_t>(state[env::kObjectsIndex]);
  for (int k = 0; k < object_bits_; ++k) out[(n_ + m_) * block_ + k] = static_cast<float>(z >> k & 1u);
}

void JointInputEncoder::EncodeJoint(const int32_t* state, const int32_t* actions, const int* order,
                                    float* out) const {
  EncodeState(state, order, out);
  float* action_part = out + state_dim_;
  std::fill(action_part, action_part + action_dim(), 0.0f);
  for (int slot = 0; slot < n_; ++slot) action_part[slot * num_actions_ + actions[order[slot]]] = 1.0f;
}

void JointInputEncoder::EncodeLocal(const int32_t* state, int agent, int32_t action, bool with_agent_id,
                                    float* out) const {
  std::fill(out, out + local_dim(with_agent_id), 0.0f);
  const int32_t cell = state[env::AgentIndex(agent)];
  out[cell / width_] = 1.0f;
  out[height_ + cell % width_] = 1.0f;
  out[block_ + action] = 1.0f;
  if (with_agent_id) out[block_ + num_actions_ + agent] = 1.0f;
}

}  // namespace imca::reward

namespace imca::reward {

void JointInputEncoder::EncodeLocalState(const int32_t* state, int agent, bool with_agent_id, float* out) const {
  std::fill(out, out + local_state_dim(with_agent_id), 0.0f);
  const int32_t cell = state[env::AgentIndex(agent)];
  out[cell / width_] = 1.0f;
  out[height_ + cell % width_] = 1.0f;
  if (with_agent_id) out[block_ + agent] = 1.0f;
}

}  // namespace imca::reward
