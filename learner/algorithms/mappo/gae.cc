#include "learner/algorithms/mappo/gae.h"

namespace imca::learner {

// Runs the recursion backwards in time, all M streams per step, so memory is
// walked contiguously. The advantage already written for step t+1 serves as
// gae_{t+1}; no scratch buffer is needed.
//
// A step that is both terminated and truncated counts as terminated (no
// bootstrap). final_values is read only at truncated steps, so a caller with
// no truncation in the block may pass nullptr.
void ComputeGae(int64_t T, int64_t M, const float* rewards, const float* values,
                const float* final_values, const bool* terminated, const bool* truncated,
                float gamma, float lambda, float* advantages, float* returns) {
  const float gamma_lambda = gamma * lambda;
  for (int64_t t = T - 1; t >= 0; --t) {
    const bool last_step = (t == T - 1);
    for (int64_t m = 0; m < M; ++m) {
      const int64_t i = t * M + m;
      float next_value;
      if (terminated[i]) {
        next_value = 0.0f;
      } else if (truncated[i]) {
        next_value = final_values[i];
      } else {
        next_value = values[i + M];
      }
      const float delta = rewards[i] + gamma * next_value - values[i];
      const bool ended = terminated[i] || truncated[i];
      const float next_gae = (ended || last_step) ? 0.0f : advantages[i + M];
      advantages[i] = delta + gamma_lambda * next_gae;
      returns[i] = advantages[i] + values[i];
    }
  }
}

void EdtiInteractionRewards(int64_t T, int64_t E, int n, const float* influences, const float* v_ext,
                            const float* v_int, const float* r_ext, const float* r_int, float gamma,
                            const EdtiCoefficients& coef, float* voi) {
  const int64_t M = E * n;
  for (int64_t t = 0; t < T; ++t) {
    for (int64_t e = 0; e < E; ++e) {
      const int64_t row = t * M + e * n, next = (t + 1) * M + e * n;
      for (int i = 0; i < n; ++i) {
        double transition = 0, partner = 0;
        for (int j = 0; j < n; ++j) {
          if (j == i) continue;
          const float c = influences[(row + i) * n + j];
          transition += c * (coef.tv_ext * v_ext[next + j] + coef.tv_int * v_int[next + j]);
          partner += coef.partner_ext * r_ext[row + j] + coef.partner_int * r_int[row + j];
        }
        voi[row + i] = static_cast<float>(coef.tv * gamma * transition + coef.partner * partner);
      }
    }
  }
}

}  // namespace imca::learner
