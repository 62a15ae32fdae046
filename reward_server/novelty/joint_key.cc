#include "reward_server/novelty/joint_key.h"

namespace imca::reward {
namespace {

int BitsFor(int64_t values) {
  int bits = 0;
  while ((int64_t{1} << bits) < values) ++bits;
  return bits;
}

uint64_t Mix(uint64_t h, uint64_t x) {
  h ^= x + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2);
  h ^= h >> 31;
  h *= 0xbf58476d1ce4e5b9ULL;
  h ^= h >> 29;
  return h;
}

}  // namespace

JointKeyCodec::JointKeyCodec(const env::Scenario& scenario)
    : n_(scenario.num_agents()),
      m_(scenario.num_npcs()),
      object_bits_(scenario.num_object_bits()),
      cell_bits_(BitsFor(scenario.map().num_cells())),
      action_bits_(BitsFor(scenario.num_actions())) {
  exact_ = object_bits_ + m_ * cell_bits_ + n_ * (cell_bits_ + action_bits_) <= 64;
}

uint64_t JointKeyCodec::GlobalKey(const int32_t* state, const int32_t* actions,
                                  const int* order) const {
  const uint64_t z = static_cast<uint32_t>(state[env::kObjectsIndex]);
  if (exact_) {
    uint64_t key = z;
    int shift = object_bits_;
    for (int j = 0; j < m_; ++j) {
      key |= static_cast<uint64_t>(state[1 + n_ + j]) << shift;
      shift += cell_bits_;
    }
    for (int slot = 0; slot < n_; ++slot) {
      const int a = order[slot];
      const uint64_t pair = static_cast<uint64_t>(state[env::AgentIndex(a)]) << action_bits_ |
                            static_cast<uint64_t>(actions[a]);
      if (shift < 64) key |= pair << shift;
      shift += cell_bits_ + action_bits_;
    }
    return key;
  }
  uint64_t h = Mix(0x243f6a8885a308d3ULL, z);
  for (int j = 0; j < m_; ++j) h = Mix(h, static_cast<uint64_t>(state[1 + n_ + j]));
  for (int slot = 0; slot < n_; ++slot) {
    const int a = order[slot];
    h = Mix(h, static_cast<uint64_t>(state[env::AgentIndex(a)]) << 8 | static_cast<uint64_t>(actions[a]));
  }
  return h;
}

void JointKeyCodec::CanonicalOrder(const int32_t* state, int* order) const {
  for (int a = 0; a < n_; ++a) order[a] = a;
  // Insertion sort: n <= 9.
  for (int i = 1; i < n_; ++i) {
    const int a = order[i];
    int j = i;
    while (j > 0 && state[env::AgentIndex(order[j - 1])] > state[env::AgentIndex(a)]) {
      order[j] = order[j - 1];
      --j;
    }
    order[j] = a;
  }
}

void JointKeyCodec::SlotOrder(const int32_t* state, bool canonical, int* order) const {
  if (canonical) {
    CanonicalOrder(state, order);
  } else {
    for (int a = 0; a < n_; ++a) order[a] = a;
  }
}

uint64_t JointKeyCodec::LocalKey(const int32_t* state, int agent, int32_t action,
                                 bool shared_across_agents) const {
  uint64_t key = static_cast<uint64_t>(state[env::AgentIndex(agent)]) << action_bits_ |
                 static_cast<uint64_t>(action);
  if (!shared_across_agents) key |= static_cast<uint64_t>(agent + 1) << (cell_bits_ + action_bits_);
  return key;
}

}  // namespace imca::reward
