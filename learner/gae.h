#ifndef IMCA_LEARNER_GAE_H_
#define IMCA_LEARNER_GAE_H_

#include <cstdint>

namespace imca::learner {

// Generalised advantage estimation over a time-major block of T steps of M
// independent streams (M = envs x agents). All arrays are [T][M] except
// `values`, which is [T+1][M] (values[T] bootstraps the last step).
//   terminated[t][m]: the episode ended at step t with no future (V = 0).
//   truncated[t][m]:  the episode hit its time limit at step t; the future is
//                     bootstrapped with final_values[t][m] = V(state reached),
//                     not with values[t+1] (which belongs to the next episode).
// After an ended step the advantage recursion restarts. Writes advantages and
// returns (= advantages + values[t]). Pure; thread-safe.
void ComputeGae(int64_t T, int64_t M, const float* rewards, const float* values,
                const float* final_values, const bool* terminated, const bool* truncated,
                float gamma, float lambda, float* advantages, float* returns);

}  // namespace imca::learner

#endif  // IMCA_LEARNER_GAE_H_
