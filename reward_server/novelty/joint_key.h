#ifndef IMCA_REWARD_SERVER_NOVELTY_JOINT_KEY_H_
#define IMCA_REWARD_SERVER_NOVELTY_JOINT_KEY_H_

#include <cstdint>

#include "common/env/env.h"

namespace imca::reward {

// Builds count-table keys from compact states and actions.
//
// A joint key encodes the object bits z, the cells of the non-player entities
// (the prey) and the agents' (cell, action) pairs in a slot order given by the
// caller (identity, canonical or a random permutation). When z bits +
// m * cell bits + n * (cell bits + action bits) fit in 64 bits the
// key is the exact bit-packing of those fields (no collisions: coop_nav 43x9
// with 2 agents needs 26 bits); otherwise it is a 64-bit mix of the same
// fields, where two distinct pairs collide with probability 2^-64 and the
// chance of any collision among N keys is about N^2 / 2^65 (3e-4 at 10^8
// keys); a collision merges two counts, which only lowers two bonuses.
// The step count t is not part of any key. Immutable; thread-safe.
class JointKeyCodec {
 public:
  explicit JointKeyCodec(const env::Scenario& scenario);

  bool exact() const { return exact_; }

  // Key of (z, (cell_{order[0]}, actions[order[0]]), ..., (cell_{order[n-1]}, ...)).
  uint64_t GlobalKey(const int32_t* state, const int32_t* actions, const int* order) const;
  // Slot order that sorts agents by cell (cells are distinct, so the order is
  // unique and the key of a permuted joint pair is identical).
  void CanonicalOrder(const int32_t* state, int* order) const;
  // Canonical order if `canonical`, else agent order: the slot order every
  // lookup of a scorer uses.
  void SlotOrder(const int32_t* state, bool canonical, int* order) const;
  // Key of agent `agent`'s local pair (cell, action); includes the agent id
  // unless `shared_across_agents`.
  uint64_t LocalKey(const int32_t* state, int agent, int32_t action, bool shared_across_agents) const;

 private:
  int n_;
  int m_;
  int object_bits_;
  int cell_bits_;
  int action_bits_;
  bool exact_;
};

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_NOVELTY_JOINT_KEY_H_
