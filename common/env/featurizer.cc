#include "common/env/featurizer.h"

#include <algorithm>
#include <cstdlib>

namespace imca::env {

Featurizer::Featurizer(const Scenario& scenario)
    : scenario_(scenario),
      n_(scenario.num_agents()),
      m_(scenario.num_npcs()),
      width_(scenario.map().width()),
      height_(scenario.map().height()),
      object_bits_(scenario.num_object_bits()),
      radius_(scenario.view_radius()) {
  global_dim_ = (n_ + m_) * (height_ + width_) + object_bits_ + 1;
  obs_dim_ = global_dim_ + n_;
}

float* Featurizer::PutCell(int32_t cell, bool visible, float* out) const {
  std::fill(out, out + height_ + width_, 0.0f);
  if (visible) {
    out[cell / width_] = 1.0f;
    out[height_ + cell % width_] = 1.0f;
  }
  return out + height_ + width_;
}

float* Featurizer::PutObjects(const int32_t* state, float* out) const {
  const uint32_t z = static_cast<uint32_t>(state[kObjectsIndex]);
  for (int k = 0; k < object_bits_; ++k) *out++ = static_cast<float>(z >> k & 1u);
  return out;
}

bool Featurizer::Visible(int32_t from, int32_t to) const {
  if (radius_ <= 0) return true;
  return std::abs(from / width_ - to / width_) <= radius_ && std::abs(from % width_ - to % width_) <= radius_;
}

void Featurizer::Observe(const int32_t* state, int agent, float* out) const {
  const int32_t self = state[AgentIndex(agent)];
  out = PutCell(self, true, out);
  for (int i = 1; i < n_; ++i) {
    const int32_t cell = state[AgentIndex((agent + i) % n_)];
    out = PutCell(cell, Visible(self, cell), out);
  }
  for (int j = 0; j < m_; ++j) {
    const int32_t cell = state[1 + n_ + j];
    out = PutCell(cell, Visible(self, cell), out);
  }
  out = PutObjects(state, out);
  std::fill(out, out + n_, 0.0f);
  out[agent] = 1.0f;
  out += n_;
  *out = static_cast<float>(state[scenario_.step_index()]) / static_cast<float>(scenario_.step_limit());
}

void Featurizer::GlobalState(const int32_t* state, float* out) const {
  for (int i = 0; i < n_ + m_; ++i) out = PutCell(state[1 + i], true, out);
  out = PutObjects(state, out);
  *out = static_cast<float>(state[scenario_.step_index()]) / static_cast<float>(scenario_.step_limit());
}

}  // namespace imca::env
