// The scenario registry: every entry builds on its bundled map under its own
// name, and a new scenario arrives as one entry (a toy here).
#include "common/env/scenarios/registry.h"

#include <memory>
#include <string>
#include <utility>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace imca::env {
namespace {

using ::testing::HasSubstr;

TEST(ScenarioRegistryTest, EveryEntryBuildsOnItsMapUnderItsOwnName) {
  ASSERT_FALSE(Scenarios().entries().empty());
  EXPECT_EQ(Scenarios().entries().front().name, "coop_nav");  // ScenarioConfig's default.
  std::string previous;
  for (const ScenarioEntry& entry : Scenarios().entries()) {
    EXPECT_LT(previous, entry.name) << "scenarios.def is in alphabetical order";
    previous = entry.name;
    ScenarioConfig config;
    config.name = entry.name;
    absl::StatusOr<std::unique_ptr<Scenario>> made = MakeScenario(config, DefaultMapDir());
    ASSERT_TRUE(made.ok()) << entry.name << ": " << made.status();
    EXPECT_EQ((*made)->name(), entry.name);
    EXPECT_EQ((*made)->num_agents(), entry.default_agents) << entry.name;
  }
}

TEST(ScenarioRegistryTest, AnUnknownOrEmptyNameIsRefusedNamingTheKnownOnes) {
  ScenarioConfig config;
  config.name = "no_such";
  absl::StatusOr<std::unique_ptr<Scenario>> made = MakeScenario(config, DefaultMapDir());
  ASSERT_FALSE(made.ok());
  EXPECT_EQ(made.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(made.status().message(), HasSubstr("--scenario: 'no_such' is not coop_nav, "));
  config.name = "";
  auto map = GridMap::Parse("1.2\n", "empty_name.txt");
  ASSERT_TRUE(map.ok());
  made = MakeScenarioWithMap(config, *std::move(map));
  ASSERT_FALSE(made.ok());
  EXPECT_THAT(made.status().message(), HasSubstr("--scenario"));
  EXPECT_FALSE(TuningOf("no_such").batch_steps.has_value());
}

// A toy: one agent steps right until the last column.
class Corridor final : public Scenario {
 public:
  Corridor(GridMap map, const ScenarioConfig& config, int n) : Scenario(std::move(map), config, n, 0, 5, 10, 1, 0) {}
  absl::string_view name() const override { return "corridor"; }
  int num_object_bits() const override { return 0; }
  StepOutcome Step(int32_t* state, const int32_t* actions, Rng& rng, float* rewards) const override {
    const int t = StepAgents(state, actions, rng);
    return Finish(t, map_.Col(state[AgentIndex(0)]) == map_.width() - 1, rewards);
  }
};

TEST(ScenarioRegistryTest, AToyArrivesAsOneEntryAndATakenNameIsRefused) {
  ScenarioRegistry registry;
  const auto no_wall = [](const GridMap& m) { return m.num_cells() > 1 ? "" : "needs two cells"; };
  ScenarioTuning tuning;
  tuning.batch_steps = 64;
  ASSERT_TRUE(registry.Add(MakeScenarioEntry<Corridor>("corridor", 1, no_wall, tuning)).ok());
  EXPECT_FALSE(registry.Add(MakeScenarioEntry<Corridor>("corridor", 1, no_wall)).ok());
  ScenarioEntry incomplete = MakeScenarioEntry<Corridor>("hollow", 1, nullptr);
  EXPECT_THAT(registry.Add(incomplete).message(), HasSubstr("lacks a hook"));

  absl::StatusOr<const ScenarioEntry*> entry = registry.Find("corridor");
  ASSERT_TRUE(entry.ok());
  EXPECT_EQ((*entry)->tuning.batch_steps, 64);
  auto map = GridMap::Parse("1..\n", "corridor.txt");
  ASSERT_TRUE(map.ok());
  ASSERT_EQ((*entry)->check(*map), "");
  std::unique_ptr<Scenario> corridor = (*entry)->make(*std::move(map), ScenarioConfig{}, 1);
  std::vector<int32_t> state(corridor->state_size());
  Rng rng(1);
  corridor->Reset(rng, state.data());
  const int32_t right = kRight;
  float reward = 0;
  EXPECT_FALSE(corridor->Step(state.data(), &right, rng, &reward).success);
  EXPECT_TRUE(corridor->Step(state.data(), &right, rng, &reward).success);
  EXPECT_EQ(reward, 1.0f);
}

}  // namespace
}  // namespace imca::env
