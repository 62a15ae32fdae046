#include "envtool/episode_io.h"

#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "common/env/env.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace imca::envtool {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;
using Steps = std::vector<std::vector<int32_t>>;

std::unique_ptr<env::Scenario> Rooms() {
  auto map = env::GridMap::Parse(
      "#########\n"   //  0.. 8
      "#1.a#..T#\n"   //  9..17
      "#2..A...#\n"   // 18..26
      "#########\n",  // 27..35
      "rooms_test_map");
  EXPECT_TRUE(map.ok()) << map.status();
  env::ScenarioConfig config;
  config.name = "multi_room";
  auto scenario = env::MakeScenarioWithMap(config, *std::move(map));
  EXPECT_TRUE(scenario.ok()) << scenario.status();
  return *std::move(scenario);
}

TEST(ActionFileTest, KeysNumbersCompactLinesAndComments) {
  auto steps = ParseActionFile("# two agents\nw d\n\n4 0   # stay, up\nsx\n  A  3\n", "moves.txt", 2, 5);
  ASSERT_TRUE(steps.ok()) << steps.status();
  EXPECT_EQ(*steps, (Steps{{env::kUp, env::kRight},
                           {env::kStay, env::kUp},
                           {env::kDown, env::kStay},
                           {env::kLeft, env::kRight}}));
}

TEST(ActionFileTest, BadTokenNamesFileLineAndColumn) {
  auto steps = ParseActionFile("w d\n# fine\nw q\n", "moves.txt", 2, 5);
  ASSERT_EQ(steps.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(steps.status().message(), HasSubstr("moves.txt:3:3: 'q' is not an action"));
}

TEST(ActionFileTest, ArityAndRangeErrors) {
  struct Case {
    const char* text;
    int num_actions;
    const char* error;
  } cases[] = {
      {"w\n", 5, "f:1:2: expected 2 actions (one per agent), got 1"},
      {"w d s\n", 5, "f:1:5: expected 2 actions (one per agent), got 3"},
      {"w 5\n", 5, "f:1:3: action 5 not in [0, 4]"},
      {"w -1\n", 5, "f:1:3: '-1' is not an action"},
      {"d\tx\n", 4, "f:1:3: 'x' (stay) is not an action here: 4 actions, keys wsad or numbers 0..3"},
      {"wdd\n", 5, "f:1:1: 'wdd' is not an action"},
  };
  for (const Case& c : cases) {
    auto steps = ParseActionFile(c.text, "f", 2, c.num_actions);
    EXPECT_THAT(steps.status().message(), HasSubstr(c.error)) << c.text;
  }
}

TEST(ActionFileTest, ReadsFilesAndNamesMissingOnes) {
  const std::string path = ::testing::TempDir() + "/actions.txt";
  std::ofstream(path) << "d\n1\n";
  auto steps = ReadActionFile(path, 1, 5);
  ASSERT_TRUE(steps.ok()) << steps.status();
  EXPECT_EQ(*steps, (Steps{{env::kRight}, {env::kDown}}));
  auto missing = ReadActionFile("/nonexistent_dir/actions.txt", 1, 5);
  EXPECT_EQ(missing.status().code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(missing.status().message(), HasSubstr("/nonexistent_dir/actions.txt"));
}

TEST(ActionLineTest, ColumnInMessage) {
  EXPECT_THAT(*ParseActionLine(" s a ", 2, 5), ElementsAre(env::kDown, env::kLeft));
  EXPECT_THAT(ParseActionLine("s ?", 2, 5).status().message(), HasSubstr("column 3: '?'"));
}

TEST(StateTest, ParsesAndValidates) {
  auto s = Rooms();
  auto state = ParseState("0, 10,19,0", *s);
  ASSERT_TRUE(state.ok()) << state.status();
  EXPECT_THAT(*state, ElementsAre(0, 10, 19, 0));
  EXPECT_THAT(ParseState("0,10,19", *s).status().message(), HasSubstr("expected 4 comma-separated"));
  EXPECT_THAT(ParseState("0,10,x,0", *s).status().message(), HasSubstr("'x' is not an integer"));
  EXPECT_THAT(ParseState("0,10,0,0", *s).status().message(), HasSubstr("agent 1"));  // A wall.
}

TEST(JsonTest, InitialAndStepObjects) {
  auto s = Rooms();
  std::vector<int32_t> state = {0, 10, 19, 0};
  EXPECT_EQ(
      StateJson(*s, state.data(), {}, {}, {}),
      "{\"t\":0,\"z\":0,\"agents\":[{\"cell\":10,\"row\":1,\"col\":1},{\"cell\":19,\"row\":2,\"col\":1}],"
      "\"npcs\":[],\"actions\":[],\"rewards\":[],\"terminated\":false,\"truncated\":false,"
      "\"success\":false,\"doors_open\":[false],\"treasures_collected\":[false],\"buttons_pressed\":[]}");
  Rng rng(1);
  std::vector<float> rewards(2);
  const std::vector<int32_t> actions = {env::kRight, env::kStay};
  const env::StepOutcome outcome = s->Step(state.data(), actions.data(), rng, rewards.data());
  EXPECT_THAT(StateJson(*s, state.data(), actions, rewards, outcome),
              HasSubstr("\"t\":1,\"z\":0,\"agents\":[{\"cell\":11,\"row\":1,\"col\":2},"));
  EXPECT_THAT(StateJson(*s, state.data(), actions, rewards, outcome),
              HasSubstr("\"actions\":[3,4],\"rewards\":[-0.1,-0.1],\"terminated\":false"));
}

TEST(JsonTest, StringsAreEscaped) {
  EXPECT_EQ(JsonString("a \"b\"\\\n\x01"), "\"a \\\"b\\\"\\\\\\n\\u0001\"");
}

}  // namespace
}  // namespace imca::envtool
