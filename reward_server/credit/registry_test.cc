// The credit rules: each reads what its entry says and computes the table of
// docs/credit.md; an unknown rule is refused naming the rules; a new rule
// arrives as one entry (a toy here).
#include "reward_server/credit/registry.h"

#include <cmath>
#include <memory>
#include <vector>

#include "common/env/env.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "reward_server/make_scorer.h"

namespace imca::reward {
namespace {

using ::testing::ElementsAre;
using ::testing::FloatNear;
using ::testing::HasSubstr;
using ::testing::Pointwise;

// The outputs of one rule over `rows` rows of 2 agents.
struct Outputs {
  explicit Outputs(int rows) : global(rows), contributions(rows * 2, -1), shares(rows * 2), agent(rows * 2) {}
  ScoreOutput out() { return {global.data(), contributions.data(), shares.data(), agent.data()}; }
  std::vector<float> global, contributions, shares, agent;
};

const CreditRuleEntry& Rule(const char* name) {
  absl::StatusOr<const CreditRuleEntry*> rule = CreditRules().Find(name);
  EXPECT_TRUE(rule.ok()) << rule.status();
  return **rule;
}

TEST(CreditRulesTest, TheRulesAreListedOnceWithWhatTheyRead) {
  EXPECT_THAT(CreditRules().Names(), ElementsAre("none", "independent", "shared", "imca"));
  EXPECT_EQ(Rule("none").reads, NoveltyReads::kNothing);
  EXPECT_EQ(Rule("independent").reads, NoveltyReads::kLocal);
  EXPECT_EQ(Rule("shared").reads, NoveltyReads::kGlobal);
  EXPECT_EQ(Rule("imca").reads, NoveltyReads::kContributions);
  for (const CreditRuleEntry& rule : CreditRules().entries()) EXPECT_FALSE(rule.help.empty()) << rule.name;
}

TEST(CreditRulesTest, EachRuleComputesItsRowOfTheTable) {
  const float global[] = {0.5f};
  const float local[] = {0.25f, 0.75f};
  const float contributions[] = {0.0f, std::log(3.0f)};
  const double divisor[] = {1.0, 2.0};
  CreditInput in{1, 2, /*beta=*/2.0, /*temperature=*/1.0};
  in.global = global;

  Outputs shared(1);
  Rule("shared").apply(in, shared.out());
  EXPECT_THAT(shared.agent, ElementsAre(1.0f, 1.0f));
  EXPECT_THAT(shared.shares, ElementsAre(0.5f, 0.5f));
  EXPECT_THAT(shared.contributions, ElementsAre(0.0f, 0.0f));
  EXPECT_EQ(shared.global[0], 1.0f);

  Outputs imca(1);
  in.contributions = contributions;
  in.divisor = divisor;
  Rule("imca").apply(in, imca.out());
  EXPECT_THAT(imca.shares, Pointwise(FloatNear(1e-6), {0.25f, 0.75f}));
  EXPECT_THAT(imca.agent, Pointwise(FloatNear(1e-6), {0.25f, 0.375f}));  // 0.75 * 1 / 2.
  EXPECT_EQ(imca.global[0], 1.0f);

  Outputs independent(1);
  CreditInput local_in{1, 2, 2.0, 1.0};
  local_in.local = local;
  Rule("independent").apply(local_in, independent.out());
  EXPECT_THAT(independent.agent, ElementsAre(0.5f, 1.5f));
  EXPECT_EQ(independent.global[0], 2.0f);
  EXPECT_THAT(independent.shares, ElementsAre(0.25f, 0.75f));

  Outputs none(1);
  Rule("none").apply(CreditInput{1, 2, 2.0, 1.0}, none.out());
  EXPECT_THAT(none.agent, ElementsAre(0.0f, 0.0f));
  EXPECT_THAT(none.shares, ElementsAre(0.5f, 0.5f));
  EXPECT_THAT(none.contributions, ElementsAre(0.0f, 0.0f));
}

TEST(CreditRulesTest, AnUnknownRuleIsRefusedNamingTheRules) {
  env::ScenarioConfig scenario_config;
  absl::StatusOr<std::unique_ptr<env::Scenario>> scenario = env::MakeScenario(scenario_config, env::DefaultMapDir());
  ASSERT_TRUE(scenario.ok()) << scenario.status();
  ScorerConfig config;
  config.credit = "imcaa";
  absl::StatusOr<std::unique_ptr<CreditScorer>> scorer = MakeScorer("count", **scenario, config);
  ASSERT_FALSE(scorer.ok());
  EXPECT_EQ(scorer.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(scorer.status().message(), "--credit: 'imcaa' is not none, independent, shared or imca");
  config.credit = "shared";
  scorer = MakeScorer("eiti", **scenario, config);
  ASSERT_FALSE(scorer.ok());
  EXPECT_THAT(scorer.status().message(), HasSubstr("(it serves: none, independent)"));
}

TEST(CreditRulesTest, AToyRuleArrivesAsOneEntry) {
  CreditRuleRegistry registry;
  // The whole global bonus to the first agent.
  const CreditRuleEntry toy{"first", "the first agent takes all", NoveltyReads::kGlobal,
                            [](const CreditInput& in, const ScoreOutput& out) {
                              for (int64_t i = 0; i < in.size; ++i) {
                                out.global_rewards[i] = static_cast<float>(in.beta) * in.global[i];
                                for (int a = 0; a < in.n; ++a) {
                                  out.contributions[i * in.n + a] = 0;
                                  out.shares[i * in.n + a] = a == 0 ? 1.0f : 0.0f;
                                  out.agent_rewards[i * in.n + a] = a == 0 ? out.global_rewards[i] : 0.0f;
                                }
                              }
                            }};
  ASSERT_TRUE(registry.Add(toy).ok());
  EXPECT_THAT(registry.Add(toy).message(), HasSubstr("'first' is registered twice"));
  EXPECT_THAT(registry.Add({"hollow", "", NoveltyReads::kGlobal, nullptr}).message(), HasSubstr("lacks a hook"));
  const float global[] = {0.5f, 1.0f};
  CreditInput in{2, 2, 1.0, 1.0};
  in.global = global;
  Outputs outputs(2);
  (*registry.Find("first"))->apply(in, outputs.out());
  EXPECT_THAT(outputs.agent, ElementsAre(0.5f, 0.0f, 1.0f, 0.0f));
}

}  // namespace
}  // namespace imca::reward
