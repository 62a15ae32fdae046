#include <algorithm>
#include <cmath>

#include "reward_server/credit/registry.h"

namespace imca::reward {

void SoftmaxShares(const float* contributions, int n, double temperature, float* shares) {
  double max = contributions[0] / temperature;
  for (int a = 1; a < n; ++a) max = std::max(max, contributions[a] / temperature);
  double sum = 0;
  for (int a = 0; a < n; ++a) sum += std::exp(contributions[a] / temperature - max);
  for (int a = 0; a < n; ++a) {
    shares[a] = static_cast<float>(std::exp(contributions[a] / temperature - max) / sum);
  }
}

// The paper's split (eq. 8-10): R_i = beta * N(S, U) handed out as
// p^a R_i, p^a = softmax_a(r^a / tau), over the kind's per-agent divisor.
absl::Status RegisterImca(CreditRuleRegistry* registry) {
  return registry->Add({"imca", "the global bonus split by the softmax of each agent's counterfactual contribution",
                        NoveltyReads::kContributions, [](const CreditInput& in, const ScoreOutput& out) {
                          const int n = in.n;
                          const float beta = static_cast<float>(in.beta);
                          for (int64_t i = 0; i < in.size; ++i) {
                            out.global_rewards[i] = beta * in.global[i];
                            float* shares = out.shares + i * n;
                            SoftmaxShares(in.contributions + i * n, n, in.temperature, shares);
                            for (int a = 0; a < n; ++a) {
                              out.agent_rewards[i * n + a] = static_cast<float>(
                                  shares[a] * out.global_rewards[i] / in.divisor[i * n + a]);
                            }
                          }
                        }});
}

}  // namespace imca::reward
