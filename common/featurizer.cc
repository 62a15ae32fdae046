#include "common/featurizer.h"

#include <algorithm>

namespace imca::env {

Featurizer::Featurizer(const Scenario& scenario)
    : scenario_(scenario),
      n_(scenario.num_agents()),
      width_(scenario.map().width()),
      height_(scenario.map().height()),
      object_bits_(scenario.num_object_bits()) {
  global_dim_ = n_ * (height_ + width_) + object_bits_ + 1;
  obs_dim_ = global_dim_ + n_;
}

float* Featurizer::PutAgent(int32_t cell, float* out) const {
  std::fill(out, out + height_ + width_, 0.0f);
  out[cell / width_] = 1.0f;
  out[height_ + cell % width_] = 1.0f;
  return out + height_ + width_;
}

float* Featurizer::PutTail(const int32_t* state, float* out) const {
  const uint32_t z = static_cast<uint32_t>(state[kObjectsIndex]);
  for (int k = 0; k < object_bits_; ++k) *out++ = static_cast<float>(z >> k & 1u);
  return out;
}

void Featurizer::Observe(const int32_t* state, int agent, float* out) const {
  for (int i = 0; i < n_; ++i) out = PutAgent(state[1 + (agent + i) % n_], out);
  out = PutTail(state, out);
  std::fill(out, out + n_, 0.0f);
  out[agent] = 1.0f;
  out += n_;
  *out = static_cast<float>(state[1 + n_]) / static_cast<float>(scenario_.step_limit());
}

void Featurizer::GlobalState(const int32_t* state, float* out) const {
  for (int a = 0; a < n_; ++a) out = PutAgent(state[1 + a], out);
  out = PutTail(state, out);
  *out = static_cast<float>(state[1 + n_]) / static_cast<float>(scenario_.step_limit());
}

}  // namespace imca::env
