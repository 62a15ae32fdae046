#include <algorithm>

#include "reward_server/credit/registry.h"

namespace imca::reward {

// No intrinsic reward: the novelty kind is not asked.
absl::Status RegisterNone(CreditRuleRegistry* registry) {
  return registry->Add({"none", "no intrinsic reward (the kind is not asked)", NoveltyReads::kNothing,
                        [](const CreditInput& in, const ScoreOutput& out) {
                          const int64_t cells = in.size * in.n;
                          std::fill(out.global_rewards, out.global_rewards + in.size, 0.0f);
                          std::fill(out.contributions, out.contributions + cells, 0.0f);
                          std::fill(out.agent_rewards, out.agent_rewards + cells, 0.0f);
                          std::fill(out.shares, out.shares + cells, 1.0f / in.n);
                        }});
}

}  // namespace imca::reward
