#include "reward_server/credit/registry.h"

namespace imca::reward {

// Every agent the whole global bonus, r_i^a = R_i = beta * N(S, U).
absl::Status RegisterShared(CreditRuleRegistry* registry) {
  return registry->Add({"shared", "every agent the whole global bonus beta * N(S, U)", NoveltyReads::kGlobal,
                        [](const CreditInput& in, const ScoreOutput& out) {
                          const int n = in.n;
                          const float beta = static_cast<float>(in.beta);
                          for (int64_t i = 0; i < in.size; ++i) {
                            out.global_rewards[i] = beta * in.global[i];
                            for (int a = 0; a < n; ++a) {
                              out.contributions[i * n + a] = 0;
                              out.agent_rewards[i * n + a] = out.global_rewards[i];
                              out.shares[i * n + a] = 1.0f / n;
                            }
                          }
                        }});
}

}  // namespace imca::reward
