#include "reward_server/credit/registry.h"

namespace imca::reward {

// Each agent its own novelty, r_i^a = beta * N_a; R_i their sum, p^a each
// agent's part of it (1 / n when the sum is 0).
absl::Status RegisterIndependent(CreditRuleRegistry* registry) {
  return registry->Add({"independent", "each agent beta times its own local novelty", NoveltyReads::kLocal,
                        [](const CreditInput& in, const ScoreOutput& out) {
                          const int n = in.n;
                          const float beta = static_cast<float>(in.beta);
                          for (int64_t i = 0; i < in.size; ++i) {
                            const float* local = in.local + i * n;
                            float* rewards = out.agent_rewards + i * n;
                            float total = 0;
                            for (int a = 0; a < n; ++a) total += rewards[a] = beta * local[a];
                            out.global_rewards[i] = total;
                            for (int a = 0; a < n; ++a) {
                              out.shares[i * n + a] = total > 0 ? rewards[a] / total : 1.0f / n;
                            }
                          }
                        }});
}

}  // namespace imca::reward
