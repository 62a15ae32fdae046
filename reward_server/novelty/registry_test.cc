#include "reward_server/novelty/registry.h"

#include <set>
#include <string>

#include "absl/flags/flag.h"
#include "common/env/env.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "reward_server/make_scorer.h"
#include "reward_server/novelty/sf_novelty.h"
#include "reward_server/reward_flags.h"

// A toy novelty kind's settings: one table, expanded into flags here as a
// kind's *_registration.cc does.
namespace imca::reward {
namespace {
struct ToyOptions {
  double level = 0.5;
};
#define IMCA_TOY_NOVELTY_SETTINGS(X) X(double, toy_level, level, "toy: the novelty of everything")
}  // namespace
}  // namespace imca::reward

IMCA_TOY_NOVELTY_SETTINGS(IMCA_SETTING_FLAG)

namespace imca::reward {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;

IMCA_SETTING_TABLE(ToySettings, ToyOptions, IMCA_TOY_NOVELTY_SETTINGS)

// Its whole registration: what a toy_registration.cc would hold. A real kind
// returns its own Novelty; the toy reuses count's, which is all the
// registry's contract needs of it.
NoveltyEntry ToyEntry() {
  return MakeNoveltyEntry<ToyOptions>(
      "toy", "a toy", &ToySettings(), [](ScorerConfig* config) { config->credit = "shared"; },
      [](const env::Scenario& scenario, const ScorerConfig& config, const ToyOptions&) {
        return MakeNovelty("count", scenario, config);
      });
}

TEST(NoveltyRegistryTest, ATakenNameOrAMissingHookIsRefused) {
  NoveltyRegistry registry;
  ASSERT_TRUE(registry.Add(ToyEntry()).ok());
  EXPECT_THAT(std::string(registry.Add(ToyEntry()).message()), HasSubstr("'toy' is registered twice"));
  NoveltyEntry hookless = ToyEntry();
  hookless.name = "toy2";
  hookless.create = nullptr;
  EXPECT_THAT(std::string(registry.Add(hookless).message()), HasSubstr("lacks a hook"));
  EXPECT_THAT(registry.Names(), ElementsAre("toy"));
  EXPECT_THAT(std::string(registry.Find("nope").status().message()), HasSubstr("--reward: 'nope' is not toy"));
}

TEST(NoveltyRegistryTest, TheToyArrivesWithItsSettingsAndFactory) {
  NoveltyRegistry registry;
  ASSERT_TRUE(registry.Add(ToyEntry()).ok());
  const NoveltyEntry& toy = **registry.Find("toy");
  EXPECT_EQ(toy.settings[0].owner, "toy");
  std::any options;
  absl::SetFlag(&FLAGS_toy_level, 0.75);
  toy.fill_from_flags(&options);
  absl::SetFlag(&FLAGS_toy_level, std::nullopt);
  JsonObject json;
  toy.add_json(options, &json);
  EXPECT_EQ(json.Text(), R"({"toy_level": 0.75})");
  auto scenario = env::MakeScenario(env::ScenarioConfig{}, env::DefaultMapDir());
  ASSERT_TRUE(scenario.ok());
  ScorerConfig config;
  toy.defaults(&config);
  EXPECT_EQ(config.credit, "shared");
  EXPECT_TRUE(toy.create(**scenario, config, options).ok());
  EXPECT_THAT(std::string(toy.create(**scenario, config, std::any(3)).status().message()),
              HasSubstr("another reward kind's"));
}

TEST(NoveltyRegistryTest, TheKindsAndTheirSettingsHaveOneNameEach) {
  EXPECT_THAT(Novelties().Names(), ElementsAre("count", "rnd", "sf", "eiti", "edti"));
  std::set<std::string> names;
  for (const SettingRow& row : RewardSettingRows()) {
    EXPECT_TRUE(names.insert(row.name).second) << row.name << " is declared twice";
    EXPECT_FALSE(row.help.empty()) << row.name;
  }
  for (const SettingRow& row : RewardSettingRows()) {
    if (row.name == "eta") {
      EXPECT_EQ(row.owner, "eiti,edti");
    }
  }
}

// Every kind builds a scorer with its defaults, and refuses another kind's
// options.
TEST(NoveltyRegistryTest, EveryKindBuildsWithItsDefaults) {
  auto scenario = env::MakeScenario(env::ScenarioConfig{}, env::DefaultMapDir());
  ASSERT_TRUE(scenario.ok());
  for (const std::string& kind : Novelties().Names()) {
    const ScorerConfig config = DefaultScorerConfig(kind, (*scenario)->name());
    auto scorer = MakeScorer(kind, **scenario, config);
    EXPECT_TRUE(scorer.ok()) << kind << ": " << scorer.status();
  }
  EXPECT_FALSE(MakeScorer("rnd", **scenario, DefaultScorerConfig("rnd", "coop_nav"), SfConfig()).ok());
}

}  // namespace
}  // namespace imca::reward
