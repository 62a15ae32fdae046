#ifndef IMCA_LEARNER_ALGORITHMS_MAPPO_GAE_H_
#define IMCA_LEARNER_ALGORITHMS_MAPPO_GAE_H_

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

// EDTI's value-of-interaction coefficients (docs/baselines.md: the values
// EDTI's code actually runs with `--r_tv`, gamma_coor_tv = gamma_coor_r = 1).
struct EdtiCoefficients {
  float tv = 1.0f;             // gamma_coor_tv: the transition term.
  float tv_ext = 0.1f;         // gamma_coor_tv_e = beta_ext.
  float tv_int = 1.0f;         // gamma_coor_tv_c = beta_int.
  float partner = 1.0f;        // gamma_coor_r: the partner-reward term.
  float partner_ext = 0.1f;    // gamma_coor_r_e.
  float partner_int = 0.1f;    // gamma_coor_r_c.
};

// EDTI's value-of-interaction reward of each agent i at each step t, as the
// released ppo2/runner.py assembles it:
//   voi_i = tv * gamma * sum_{j != i} c_{i->j} (tv_ext V_ext_j(t+1) + tv_int V_int_j(t+1))
//         + partner * sum_{j != i} (partner_ext r_ext_j + partner_int r_int_j)
// over T steps of E envs of n agents: influences [T][E][n][n] (i major),
// v_ext / v_int [T+1][E][n] (denormalised values of the states of the unroll;
// at an episode end row t+1 is the next episode's first state, as EDTI does
// not mask it), r_ext / r_int [T][E][n] (extrinsic reward and the server's
// curiosity). Writes voi [T][E][n]. Pure; thread-safe.
void EdtiInteractionRewards(int64_t T, int64_t E, int n, const float* influences, const float* v_ext,
                            const float* v_int, const float* r_ext, const float* r_int, float gamma,
                            const EdtiCoefficients& coef, float* voi);

}  // namespace imca::learner

#endif  // IMCA_LEARNER_ALGORITHMS_MAPPO_GAE_H_
