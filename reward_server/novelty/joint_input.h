#ifndef IMCA_REWARD_SERVER_NOVELTY_JOINT_INPUT_H_
#define IMCA_REWARD_SERVER_NOVELTY_JOINT_INPUT_H_

#include <cstdint>

#include "common/env/env.h"

namespace imca::reward {

// Float encodings of joint states and joint state-actions for the learned
// novelty models (RND, SF). Agents appear in a slot order given by the caller
// (identity, canonical or a random permutation), so permuted joint pairs can
// map to the same input.
//   state part, state_dim floats: for each slot the agent's [row one-hot H |
//     col one-hot W]; then each entity's (the prey); then z as bits. (No t:
//     novelty is of the situation, not of the clock, as for count keys.)
//   action part, n * A floats: for each slot the agent's action one-hot.
//   local input (independent credit), local_dim floats: one agent's
//     [row | col] one-hot, its action one-hot, and (unless shared across
//     agents) its id one-hot.
// Immutable; thread-safe.
class JointInputEncoder {
 public:
  explicit JointInputEncoder(const env::Scenario& scenario);

  int state_dim() const { return state_dim_; }
  int action_dim() const { return n_ * num_actions_; }
  int joint_dim() const { return state_dim_ + action_dim(); }
  int local_dim(bool with_agent_id) const { return block_ + num_actions_ + (with_agent_id ? n_ : 0); }

  // Writes state_dim floats: `state` with agents in slot order `order`.
  void EncodeState(const int32_t* state, const int* order, float* out) const;
  // Writes joint_dim floats: EncodeState, then the actions in slot order.
  void EncodeJoint(const int32_t* state, const int32_t* actions, const int* order, float* out) const;
  int local_state_dim(bool with_agent_id) const { return block_ + (with_agent_id ? n_ : 0); }
  // Writes local_state_dim floats: agent `agent`'s [row | col] one-hot (+ id).
  void EncodeLocalState(const int32_t* state, int agent, bool with_agent_id, float* out) const;
  // Writes local_dim(with_agent_id) floats for agent `agent` taking `action`.
  void EncodeLocal(const int32_t* state, int agent, int32_t action, bool with_agent_id, float* out) const;

 private:
  int n_;
  int m_;
  int num_actions_;
  int width_;
  int height_;
  int object_bits_;
  int block_;
  int state_dim_;
};

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_NOVELTY_JOINT_INPUT_H_
