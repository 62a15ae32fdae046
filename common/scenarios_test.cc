// One test per rule of SPEC section 7, with scripted action sequences on
// small maps (cells are row * width + col).
#include <memory>
#include <string>
#include <vector>

#include "common/env.h"
#include "common/vec_env.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace imca::env {
namespace {

std::unique_ptr<Scenario> Make(const std::string& name, const char* text, int step_limit = 0,
                               ScenarioConfig config = {}) {
  auto map = GridMap::Parse(text, name + "_test_map");
  EXPECT_TRUE(map.ok()) << map.status();
  config.name = name;
  config.step_limit = step_limit;
  auto scenario = MakeScenarioWithMap(config, *std::move(map));
  EXPECT_TRUE(scenario.ok()) << scenario.status();
  return *std::move(scenario);
}

// Drives one environment from a given state.
struct Episode {
  const Scenario& scenario;
  std::vector<int32_t> state;
  Rng rng{11};
  std::vector<float> rewards = std::vector<float>(kMaxAgents);
  StepOutcome Step(std::vector<int32_t> actions) {
    return scenario.Step(state.data(), actions.data(), rng, rewards.data());
  }
  int32_t cell(int agent) const { return state[AgentIndex(agent)]; }
};

// multi_room: three agents; door A (cell 22) between the rooms; its switch
// 'a' at cell 12 is two cells from the door.
constexpr char kRooms[] =
    "#########\n"   //  0.. 8
    "#1.a#...#\n"   //  9..17
    "#2..A..T#\n"   // 18..26
    "#3..#...#\n"   // 27..35
    "#########\n";  // 36..44

TEST(DoorTest, OneCellDoorOpensOnlyWhileASwitchIsHeld) {
  auto s = Make("multi_room", kRooms, 0, [] { ScenarioConfig c; c.num_agents = 3; return c; }());
  Episode ep{*s, {0, 10, 19, 28, 0}};
  ep.Step({kStay, kRight, kStay});
  ep.Step({kStay, kRight, kStay});
  ASSERT_EQ(ep.cell(1), 21);  // Next to the door.
  ep.Step({kStay, kRight, kStay});
  EXPECT_EQ(ep.cell(1), 21) << "closed door entered";
  ep.Step({kRight, kStay, kStay});
  ep.Step({kRight, kStay, kStay});
  ASSERT_EQ(ep.cell(0), 12);  // On the switch.
  EXPECT_TRUE(s->DoorOpen(ep.state.data(), 0));
  ep.Step({kStay, kRight, kStay});
  EXPECT_EQ(ep.cell(1), 22) << "open door not entered";
  // The door cell holds one agent: agent 3 cannot follow while agent 2 is in it.
  ep.Step({kStay, kStay, kUp});
  ep.Step({kStay, kStay, kRight});
  ep.Step({kStay, kStay, kRight});
  ASSERT_EQ(ep.cell(2), 21);
  ep.Step({kStay, kStay, kRight});
  EXPECT_EQ(ep.cell(2), 21);
  ep.Step({kStay, kRight, kStay});  // Agent 2 goes through...
  EXPECT_EQ(ep.cell(1), 23);
  ep.Step({kLeft, kStay, kStay});   // ...and agent 1 leaves the switch: the door closes.
  EXPECT_FALSE(s->DoorOpen(ep.state.data(), 0));
  ep.Step({kStay, kStay, kRight});
  EXPECT_EQ(ep.cell(2), 21) << "door stayed open after the switch was left";
  EXPECT_EQ(s->Render(ep.state.data()).substr(0, 40), "#########\n#.1a#...#\n#..3A2.T#\n#...#...#\n");
}

TEST(DoorTest, TwoAgentsContestingTheDoorCellOneGetsIt) {
  // Agent 3 holds the switch; agents 1 and 2 step into the door from both sides.
  auto s = Make("multi_room",
                "#######\n"
                "#1.A.2#\n"
                "#a#####\n"
                "#3#T..#\n"
                "#######\n",
                0, [] { ScenarioConfig c; c.num_agents = 3; return c; }());
  for (uint64_t seed = 0; seed < 40; ++seed) {
    Episode ep{*s, {1, 8, 12, 15, 0}};  // Agent 3 on the switch.
    ep.rng = Rng(seed);
    ep.Step({kRight, kLeft, kStay});
    ep.Step({kRight, kLeft, kStay});  // Both want cell 10.
    EXPECT_NE(ep.cell(0) == 10, ep.cell(1) == 10) << seed;
  }
}

// pass: door A at cell 14; agent 1's switch at cell 12 (hold 8 steps).
constexpr char kPass[] =
    "##########\n"   //  0.. 9
    "#1a.#...G#\n"   // 10..19
    "#2..A....#\n"   // 20..29
    "##########\n";

TEST(DoorTest, EdtiDoorClosesEightStepsAfterTheSwitchIsLeft) {
  for (int wait = 7; wait <= 8; ++wait) {
    auto s = Make("pass", kPass);
    EXPECT_EQ(s->num_actions(), 4);
    Episode ep{*s, {0, 11, 21, 0}};
    ep.Step({kRight, kRight});  // Agent 1 onto the switch, agent 2 to cell 22.
    ep.Step({kLeft, kRight});   // Agent 1 leaves the switch; agent 2 at 23, next to the door.
    ASSERT_EQ(ep.cell(0), 11);
    ASSERT_EQ(ep.cell(1), 23);
    for (int k = 0; k < wait; ++k) {
      EXPECT_TRUE(s->DoorOpen(ep.state.data(), 0)) << "step " << k;
      ep.Step({kLeft, kDown});  // Both bump into walls.
    }
    // The door is open for exactly 8 moves after the switch was left.
    EXPECT_EQ(s->DoorOpen(ep.state.data(), 0), wait < 8);
    ep.Step({kLeft, kRight});
    EXPECT_EQ(ep.cell(1) == 24, wait < 8) << "wait " << wait;
  }
}

TEST(PassTest, BothAgentsPastTheWallSucceedWithTheirReward) {
  auto s = Make("pass", kPass);
  Episode ep{*s, {0, 16, 25, 0}};  // Agent 1 at 16 (past the wall), agent 2 at 25.
  const StepOutcome out = ep.Step({kRight, kLeft});
  EXPECT_TRUE(out.success);
  EXPECT_TRUE(out.terminated);
  EXPECT_FLOAT_EQ(ep.rewards[0], 1000.0f);
  EXPECT_FLOAT_EQ(ep.rewards[1], 1000.0f);
}

// predator_prey on a 5x5 field: top 5 rows... here the top 2 rows are zone.
constexpr char kField[] =
    "ZZZZZ\n"   //  0.. 4
    "ZZZZZ\n"   //  5.. 9
    ".....\n"   // 10..14
    ".....\n"   // 15..19
    "SSSSS\n";  // 20..24

TEST(PredatorPreyTest, CaptureNeedsAllFourNeighboursBlocked) {
  auto s = Make("predator_prey", kField);
  ASSERT_EQ(s->num_npcs(), 1);
  ASSERT_EQ(s->state_size(), 7);
  // Prey in the corner (0): boundary on two sides, predators move to 1 and 5.
  Episode corner{*s, {0, 2, 10, 22, 24, 0, 0}};
  StepOutcome out = corner.Step({kLeft, kUp, kStay, kStay});
  EXPECT_TRUE(out.success);
  EXPECT_TRUE(out.terminated);
  for (int a = 0; a < 4; ++a) EXPECT_FLOAT_EQ(corner.rewards[a], 20.0f);
  // Prey on the top edge (2) needs predators at 1, 3 and 7.
  for (uint64_t seed = 0; seed < 20; ++seed) {
    Episode edge{*s, {0, 1, 3, 12, 24, 2, 0}};
    edge.rng = Rng(seed);
    out = edge.Step({kStay, kStay, kStay, kStay});  // 7 is free: never caught.
    EXPECT_FALSE(out.terminated) << seed;
  }
  Episode edge{*s, {0, 1, 3, 12, 24, 2, 0}};
  out = edge.Step({kStay, kStay, kUp, kStay});  // Predator 3 to 7: caught.
  EXPECT_TRUE(out.success);
}

TEST(PredatorPreyTest, WallsBlockLikePredators) {
  auto s = Make("predator_prey",
                "#Z#\n"
                "#Z#\n"
                "S.S\n"
                "SSS\n");
  Episode ep{*s, {0, 6, 8, 9, 11, 1, 0}};  // Prey at 1; opening below it at 4.
  const StepOutcome out = ep.Step({kStay, kStay, kStay, kStay});
  EXPECT_FALSE(out.terminated);
  Episode blocked{*s, {0, 4, 8, 9, 11, 1, 0}};  // Predator in the opening.
  EXPECT_TRUE(blocked.Step({kStay, kStay, kStay, kStay}).success);
}

TEST(PredatorPreyTest, PreyNeverLeavesTheTopRows) {
  auto scenario = MakeScenario([] { ScenarioConfig c; c.name = "predator_prey"; return c; }(),
                               DefaultMapDir());
  ASSERT_TRUE(scenario.ok()) << scenario.status();
  const Scenario& s = **scenario;
  VecEnv envs(&s, 16, 3);
  std::vector<int32_t> actions(16 * 4), reached(16 * s.state_size());
  std::vector<float> rewards(16 * 4);
  bool term[16], trunc[16];
  Rng rng(4);
  for (int t = 0; t < 3000; ++t) {
    for (auto& u : actions) u = static_cast<int32_t>(rng.Uniform(5));
    envs.Step(actions.data(), rewards.data(), term, trunc, reached.data());
    for (int e = 0; e < 16; ++e) {
      const int prey = envs.states()[e * s.state_size() + 5];
      ASSERT_LT(s.map().Row(prey), 5);
      ASSERT_TRUE(s.map().InPreyZone(prey));
    }
  }
}

TEST(TwinButtonsTest, ButtonsMustBePressedOnTheSameStep) {
  auto s = Make("twin_buttons", "X12X\n");
  Episode ep{*s, {0, 1, 2, 0}};
  StepOutcome out = ep.Step({kLeft, kStay});  // Button 0 only.
  EXPECT_FALSE(out.terminated);
  EXPECT_EQ(ep.state[0], 1);
  EXPECT_FLOAT_EQ(ep.rewards[0], -0.1f);
  out = ep.Step({kRight, kRight});  // Button 1 only: the first was released.
  EXPECT_FALSE(out.terminated);
  EXPECT_EQ(ep.state[0], 2);
  out = ep.Step({kLeft, kStay});  // Both at once.
  EXPECT_TRUE(out.success);
  EXPECT_TRUE(out.terminated);
  EXPECT_FLOAT_EQ(ep.rewards[0], 49.9f);
  EXPECT_FLOAT_EQ(ep.rewards[1], 49.9f);
}

TEST(MultiRoomTest, SuccessNeedsBothInTheLastRoomAndOneOnTheTreasure) {
  auto s = Make("multi_room", kRooms);
  Episode ep{*s, {0, 15, 24, 0}};  // Both in the last room, agent 2 next to T (25).
  StepOutcome out = ep.Step({kStay, kStay});
  EXPECT_FALSE(out.terminated);
  EXPECT_FLOAT_EQ(ep.rewards[0], -0.1f);
  out = ep.Step({kStay, kRight});
  EXPECT_TRUE(out.success);
  EXPECT_FLOAT_EQ(ep.rewards[0], 49.9f);
  Episode outside{*s, {0, 10, 24, 0}};  // Agent 1 still in the first room.
  EXPECT_FALSE(outside.Step({kStay, kRight}).terminated);
}

TEST(ScenarioRulesTest, RewardsAreConfigurable) {
  ScenarioConfig config;
  config.success_reward = 7;
  config.step_penalty = 0.5;
  auto s = Make("twin_buttons", "X12X\n", 0, config);
  Episode ep{*s, {0, 1, 2, 0}};
  EXPECT_TRUE(ep.Step({kLeft, kRight}).success);
  EXPECT_FLOAT_EQ(ep.rewards[0], 6.5f);
}

TEST(ScenarioRulesTest, EveryScenarioTruncatesAtItsLimitWithoutTerminating) {
  for (const std::string& name : ScenarioNames()) {
    ScenarioConfig config;
    config.name = name;
    config.step_limit = 3;
    auto scenario = MakeScenario(config, DefaultMapDir());
    ASSERT_TRUE(scenario.ok()) << name << ": " << scenario.status();
    const Scenario& s = **scenario;
    std::vector<int32_t> state(s.state_size());
    Rng rng(1);
    s.Reset(rng, state.data());
    ASSERT_TRUE(s.ValidateState(state.data()).ok()) << name;
    std::vector<int32_t> actions(s.num_agents(), kUp);
    std::vector<float> rewards(s.num_agents());
    for (int t = 1; t <= 3; ++t) {
      const StepOutcome out = s.Step(state.data(), actions.data(), rng, rewards.data());
      EXPECT_EQ(out.truncated, t == 3) << name;
      EXPECT_FALSE(out.terminated) << name;
    }
  }
}

TEST(ScenarioRulesTest, RandomPlayKeepsEveryStateValid) {
  for (const std::string& name : ScenarioNames()) {
    ScenarioConfig config;
    config.name = name;
    auto scenario = MakeScenario(config, DefaultMapDir());
    ASSERT_TRUE(scenario.ok()) << name << ": " << scenario.status();
    const Scenario& s = **scenario;
    const int envs = 8, n = s.num_agents(), k = s.state_size();
    VecEnv vec(&s, envs, 9);
    std::vector<int32_t> actions(envs * n), reached(envs * k);
    std::vector<float> rewards(envs * n);
    bool term[envs], trunc[envs];
    Rng rng(2);
    for (int t = 0; t < 1000; ++t) {
      for (auto& u : actions) u = static_cast<int32_t>(rng.Uniform(s.num_actions()));
      vec.Step(actions.data(), rewards.data(), term, trunc, reached.data());
      for (int e = 0; e < envs; ++e) {
        ASSERT_TRUE(s.ValidateState(reached.data() + e * k).ok()) << name << "\n" << s.Render(reached.data() + e * k);
        ASSERT_TRUE(s.ValidateState(vec.states() + e * k).ok()) << name;
      }
    }
  }
}

TEST(ScenarioRulesTest, FingerprintTellsMapsAndRulesApart) {
  const uint64_t base = Make("twin_buttons", "X12X\n")->fingerprint();
  EXPECT_EQ(Make("twin_buttons", "X12X\n")->fingerprint(), base);
  EXPECT_NE(Make("twin_buttons", "X12.X\n")->fingerprint(), base);
  EXPECT_NE(Make("twin_buttons", "X12X\n", 50)->fingerprint(), base);
  ScenarioConfig rewards;
  rewards.success_reward = 10;
  EXPECT_NE(Make("twin_buttons", "X12X\n", 0, rewards)->fingerprint(), base);
  EXPECT_NE(Make("coop_nav", "T12X\n")->fingerprint(), Make("twin_buttons", "T12X\n")->fingerprint());
}

TEST(ScenarioRulesTest, MapsLackingWhatTheRulesNeedAreRejected) {
  auto map = GridMap::Parse("1..2\n", "bare.txt");
  ASSERT_TRUE(map.ok());
  for (const char* name : {"coop_nav", "multi_room", "twin_buttons", "pass", "predator_prey"}) {
    ScenarioConfig config;
    config.name = name;
    auto scenario = MakeScenarioWithMap(config, *map);
    EXPECT_FALSE(scenario.ok()) << name;
    EXPECT_THAT(scenario.status().message(), ::testing::HasSubstr("bare.txt")) << name;
  }
  auto orphan = GridMap::Parse("#a.#\n", "orphan.txt");
  ASSERT_FALSE(orphan.ok());
  EXPECT_THAT(orphan.status().message(), ::testing::HasSubstr("orphan.txt:1:2"));
}

}  // namespace
}  // namespace imca::env
