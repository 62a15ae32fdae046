#include <memory>
#include <vector>

#include "common/env/env.h"
#include "common/env/featurizer.h"
#include "common/env/vec_env.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace imca::env {
namespace {

using ::testing::HasSubstr;

std::unique_ptr<Scenario> Make(const char* text, int step_limit = 100) {
  auto map = GridMap::Parse(text, "test_map");
  EXPECT_TRUE(map.ok()) << map.status();
  ScenarioConfig config;
  config.step_limit = step_limit;
  auto scenario = MakeScenarioWithMap(config, *std::move(map));
  EXPECT_TRUE(scenario.ok()) << scenario.status();
  return *std::move(scenario);
}

// State layout [z, cell_1, cell_2, t].
struct Stepper {
  const Scenario& scenario;
  std::vector<int32_t> state;
  Rng rng{7};
  float rewards[kMaxAgents] = {};
  StepOutcome Step(std::vector<int32_t> actions) {
    return scenario.Step(state.data(), actions.data(), rng, rewards);
  }
};

TEST(GridMapTest, ParsesLegendAndSkipsComments) {
  auto map = GridMap::Parse("; comment\n#####\n#1.T#\n#S.2#\n#####\n", "m");
  ASSERT_TRUE(map.ok()) << map.status();
  EXPECT_EQ(map->width(), 5);
  EXPECT_EQ(map->height(), 4);
  EXPECT_TRUE(map->IsWall(0));
  EXPECT_FALSE(map->IsWall(6));
  EXPECT_EQ(map->FixedSpawn(0), 6);
  EXPECT_EQ(map->FixedSpawn(1), 13);
  EXPECT_THAT(map->treasures(), ::testing::ElementsAre(8));
  EXPECT_THAT(map->random_spawns(), ::testing::ElementsAre(11));
}

TEST(GridMapTest, BadCharacterNamesLineAndColumn) {
  auto map = GridMap::Parse("###\n#.#\n#x#\n", "bad.txt");
  ASSERT_FALSE(map.ok());
  EXPECT_EQ(map.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(map.status().message(), HasSubstr("bad.txt:3:2"));
}

TEST(GridMapTest, ANonPrintableByteIsEscapedInTheMessage) {
  auto map = GridMap::Parse("###\n#\xbf#\n###\n", "latin1.txt");
  ASSERT_FALSE(map.ok());
  EXPECT_THAT(std::string(map.status().message()), HasSubstr("latin1.txt:2:2: unknown map character '\\xbf'"));
}

TEST(GridMapTest, RaggedRowIsAnError) {
  auto map = GridMap::Parse("###\n#.\n", "ragged.txt");
  ASSERT_FALSE(map.ok());
  EXPECT_THAT(map.status().message(), HasSubstr("ragged.txt:2"));
}

TEST(GridMapTest, MissingFileIsNotFound) {
  EXPECT_EQ(GridMap::Load("/nonexistent/map.txt").status().code(), absl::StatusCode::kNotFound);
}

TEST(ScenarioTest, ANegativeAgentCountIsRejected) {
  ScenarioConfig config;
  config.num_agents = -1;
  auto scenario = MakeScenario(config, DefaultMapDir());
  ASSERT_FALSE(scenario.ok());
  EXPECT_THAT(std::string(scenario.status().message()), HasSubstr("num_agents -1 is negative"));
}

TEST(ScenarioTest, UnknownScenarioIsRejected) {
  ScenarioConfig config;
  config.name = "chess";
  auto scenario = MakeScenario(config, DefaultMapDir());
  ASSERT_FALSE(scenario.ok());
  EXPECT_THAT(scenario.status().message(), HasSubstr("chess"));
}

TEST(ScenarioTest, BundledMapLoads) {
  auto scenario = MakeScenario(ScenarioConfig{}, DefaultMapDir());
  ASSERT_TRUE(scenario.ok()) << scenario.status();
  EXPECT_EQ((*scenario)->num_agents(), 2);
  EXPECT_EQ((*scenario)->state_size(), 4);
}

// Row-major 5x5 cells: cell = row * 5 + col.
constexpr char kOpen[] =
    "#####\n"
    "#1..#\n"
    "#...#\n"
    "#..2#\n"
    "##T##\n";

TEST(MoveTest, WallsAndBoundaryBlock) {
  auto s = Make("1.T\n.#.\n2..\n");
  Stepper st{*s, {0, 0, 6, 0}};
  st.Step({kUp, kUp});  // Agent 1 off the top edge, agent 2 into floor cell 3.
  EXPECT_EQ(st.state[1], 0);
  EXPECT_EQ(st.state[2], 3);
  st.Step({kDown, kRight});  // Agent 1 into agent 2 (which moves right into wall 4).
  EXPECT_EQ(st.state[1], 0);  // Blocked: agent 2 stayed.
  EXPECT_EQ(st.state[2], 3);
}

TEST(MoveTest, ContestedCellGoesToExactlyOneAgent) {
  int wins1 = 0, wins2 = 0;
  for (uint64_t seed = 0; seed < 200; ++seed) {
    auto s = Make(kOpen);
    Stepper st{*s, {0, 7, 17, 0}};  // Agent 1 at (1,2), agent 2 at (3,2)... both go to (2,2).
    st.state[1] = 7;
    st.state[2] = 17;
    st.rng = Rng(seed);
    st.Step({kDown, kUp});
    const bool one_moved = (st.state[1] == 12) != (st.state[2] == 12);
    ASSERT_TRUE(one_moved) << "seed " << seed;
    (st.state[1] == 12 ? wins1 : wins2)++;
  }
  // The priority is random: both agents win sometimes.
  EXPECT_GT(wins1, 50);
  EXPECT_GT(wins2, 50);
}

TEST(MoveTest, SwapIsBlockedButFollowingWorks) {
  auto s = Make(kOpen);
  Stepper st{*s, {0, 6, 7, 0}};
  st.Step({kRight, kLeft});  // Swap: both stay.
  EXPECT_EQ(st.state[1], 6);
  EXPECT_EQ(st.state[2], 7);
  st.Step({kRight, kRight});  // Agent 1 follows agent 2 into its vacated cell.
  EXPECT_EQ(st.state[1], 7);
  EXPECT_EQ(st.state[2], 8);
  st.Step({kRight, kStay});  // Into an agent that stays: fails.
  EXPECT_EQ(st.state[1], 7);
}

TEST(CoopNavTest, RewardsPenaltyCollectionAndSuccess) {
  auto s = Make("1T.T2\n");
  Stepper st{*s, {0, 0, 4, 0}};
  StepOutcome out = st.Step({kRight, kStay});
  EXPECT_EQ(st.state[0], 1);  // Treasure 0 (cell 1) collected.
  EXPECT_FALSE(out.terminated);
  EXPECT_FLOAT_EQ(st.rewards[0], -0.1f);
  EXPECT_FLOAT_EQ(st.rewards[1], -0.1f);
  out = st.Step({kLeft, kLeft});  // Agent 2 steps on treasure 1 (cell 3).
  EXPECT_TRUE(out.terminated);
  EXPECT_TRUE(out.success);
  EXPECT_FALSE(out.truncated);
  EXPECT_FLOAT_EQ(st.rewards[0], 49.9f);
  EXPECT_FLOAT_EQ(st.rewards[1], 49.9f);
}

TEST(CoopNavTest, TruncationAtStepLimitIsNotTermination) {
  auto s = Make("1..T2\n", /*step_limit=*/3);
  Stepper st{*s, {0, 0, 4, 0}};
  EXPECT_FALSE(st.Step({kStay, kStay}).truncated);
  EXPECT_FALSE(st.Step({kStay, kStay}).truncated);
  const StepOutcome out = st.Step({kStay, kStay});
  EXPECT_TRUE(out.truncated);
  EXPECT_FALSE(out.terminated);
  EXPECT_FALSE(out.success);
}

TEST(ScenarioTest, RenderShowsWallsTreasuresAndAgents) {
  auto s = Make("1..T2\n");
  const std::vector<int32_t> state = {0, 1, 4, 7};
  EXPECT_EQ(s->Render(state.data()), ".1.T2\nt=7 z=0\n");
  const std::vector<int32_t> collected = {1, 1, 4, 7};
  EXPECT_EQ(s->Render(collected.data()), ".1..2\nt=7 z=1\n");
}

TEST(ScenarioTest, ValidateStateNamesTheElement) {
  auto s = Make(kOpen);
  std::vector<int32_t> state = {0, 6, 0, 0};  // Cell 0 is a wall.
  absl::Status status = s->ValidateState(state.data());
  EXPECT_THAT(status.message(), HasSubstr("agent 1"));
  state = {0, 6, 7, 101};
  EXPECT_THAT(s->ValidateState(state.data()).message(), HasSubstr("step count"));
  state = {4, 6, 7, 0};  // One treasure: only bit 0 exists.
  EXPECT_THAT(s->ValidateState(state.data()).message(), HasSubstr("object bits"));
}

TEST(VecEnvTest, SameSeedSameTrajectoryAndAutoReset) {
  auto scenario = MakeScenario(ScenarioConfig{}, DefaultMapDir());
  ASSERT_TRUE(scenario.ok());
  const int envs = 8, n = 2, k = 4;
  VecEnv a(scenario->get(), envs, 42), b(scenario->get(), envs, 42);
  std::vector<int32_t> actions(envs * n);
  std::vector<float> rewards(envs * n);
  bool term[envs], trunc[envs];
  std::vector<int32_t> reached(envs * k);
  Rng rng(3);
  int truncations = 0;
  for (int t = 0; t < 250; ++t) {
    for (auto& u : actions) u = rng.Uniform(5);
    a.Step(actions.data(), rewards.data(), term, trunc, reached.data());
    b.Step(actions.data(), rewards.data(), term, trunc, reached.data());
    for (int e = 0; e < envs; ++e) truncations += trunc[e];
    ASSERT_EQ(std::vector<int32_t>(a.states(), a.states() + envs * k),
              std::vector<int32_t>(b.states(), b.states() + envs * k));
  }
  EXPECT_GE(truncations, envs);  // 250 steps > 2 episodes of 100 unless solved.
  std::vector<EpisodeEnd> finished;
  a.TakeFinished(&finished);
  EXPECT_GE(static_cast<int>(finished.size()), envs * 2);
  for (int e = 0; e < envs; ++e) EXPECT_LT(a.states()[e * k + 3], 100);
}

TEST(FeaturizerTest, OneHotLayoutRelativeOrderAndAgentId) {
  auto s = Make(kOpen);
  Featurizer f(*s);
  EXPECT_EQ(f.global_dim(), 2 * (5 + 5) + 1 + 1);
  EXPECT_EQ(f.obs_dim(), f.global_dim() + 2);
  const std::vector<int32_t> state = {1, 6, 18, 50};  // (1,1) and (3,3).
  std::vector<float> obs(f.obs_dim());
  f.Observe(state.data(), 1, obs.data());
  // Agent 2 first: row 3, col 3; then agent 1: row 1, col 1.
  EXPECT_EQ(obs[3], 1.0f);
  EXPECT_EQ(obs[5 + 3], 1.0f);
  EXPECT_EQ(obs[10 + 1], 1.0f);
  EXPECT_EQ(obs[15 + 1], 1.0f);
  EXPECT_EQ(obs[20], 1.0f);      // Treasure bit.
  EXPECT_EQ(obs[21], 0.0f);      // Agent id one-hot: agent 2.
  EXPECT_EQ(obs[22], 1.0f);
  EXPECT_FLOAT_EQ(obs[23], 0.5f);  // t / limit.
  float sum = 0;
  for (float x : obs) sum += x;
  EXPECT_FLOAT_EQ(sum, 4 + 1 + 1 + 0.5f);
}

TEST(FeaturizerTest, ViewRadiusHidesFarAgentsAndThePrey) {
  auto map = GridMap::Parse("ZZZZZ\nZZZZZ\n.....\n.....\nSSSSS\n", "field");
  ASSERT_TRUE(map.ok());
  ScenarioConfig config;
  config.name = "predator_prey";
  config.view_radius = 1;
  auto s = MakeScenarioWithMap(config, *std::move(map));
  ASSERT_TRUE(s.ok()) << s.status();
  Featurizer f(**s);
  const int block = 5 + 5;
  EXPECT_EQ(f.obs_dim(), 5 * block + 0 + 4 + 1);
  // Predators at 20 (4,0), 16 (3,1), 24 (4,4), 14 (2,4); prey at 0 (0,0).
  const std::vector<int32_t> state = {0, 20, 16, 24, 14, 0, 0};
  std::vector<float> obs(f.obs_dim());
  f.Observe(state.data(), 0, obs.data());
  auto visible = [&](int slot) {
    float sum = 0;
    for (int i = 0; i < block; ++i) sum += obs[slot * block + i];
    return sum;
  };
  EXPECT_EQ(visible(0), 2.0f);  // Itself.
  EXPECT_EQ(visible(1), 2.0f);  // Predator 2, one cell diagonally: seen.
  EXPECT_EQ(visible(2), 0.0f);  // Predator 3, four columns away: hidden.
  EXPECT_EQ(visible(3), 0.0f);  // Predator 4: hidden.
  EXPECT_EQ(visible(4), 0.0f);  // The prey, four rows away: hidden.
  std::vector<float> global(f.global_dim());
  f.GlobalState(state.data(), global.data());
  float sum = 0;
  for (float x : global) sum += x;
  EXPECT_EQ(sum, 10.0f);  // The critic sees everyone.
}

}  // namespace
}  // namespace imca::env

namespace imca::env {
namespace {

// spread: -sum over landmarks of the distance to the nearest agent, the same
// for every agent, every step; no early end; success iff all are covered at
// the last step.
TEST(SpreadTest, DenseRewardIsMinusTheLandmarksDistanceToTheNearestAgent) {
  ScenarioConfig config;
  config.name = "spread";
  config.num_agents = 2;
  config.step_limit = 3;
  auto map = GridMap::Parse("#######\n#T...T#\n#.S.S.#\n#######\n", "spread_test");
  ASSERT_TRUE(map.ok()) << map.status();
  auto scenario = MakeScenarioWithMap(config, *std::move(map));
  ASSERT_TRUE(scenario.ok()) << scenario.status();
  const Scenario& s = **scenario;
  const GridMap& m = s.map();
  std::vector<int32_t> state(s.state_size(), 0);
  state[AgentIndex(0)] = 2 * m.width() + 2;  // Row 2, col 2.
  state[AgentIndex(1)] = 2 * m.width() + 4;  // Row 2, col 4.
  ASSERT_TRUE(s.ValidateState(state.data()).ok());
  Rng rng(1);
  float rewards[kMaxAgents];
  // Both stay: landmark (1,1) is sqrt(2) from agent 0, landmark (1,5) sqrt(2) from agent 1.
  int32_t stay[2] = {kStay, kStay};
  StepOutcome out = s.Step(state.data(), stay, rng, rewards);
  EXPECT_NEAR(rewards[0], -2 * std::sqrt(2.0), 1e-5);
  EXPECT_EQ(rewards[1], rewards[0]);
  EXPECT_FALSE(out.terminated || out.truncated || out.success);
  // Agent 0 up-left onto its landmark in two moves; agent 1 stays.
  int32_t up_left[2][2] = {{kUp, kStay}, {kLeft, kStay}};
  out = s.Step(state.data(), up_left[0], rng, rewards);
  EXPECT_NEAR(rewards[0], -(1.0 + std::sqrt(2.0)), 1e-5);  // Agent 0 at (1,2): 1 from (1,1).
  out = s.Step(state.data(), up_left[1], rng, rewards);
  EXPECT_NEAR(rewards[0], -std::sqrt(2.0), 1e-5);
  EXPECT_TRUE(out.truncated);  // The step limit, never a termination.
  EXPECT_FALSE(out.terminated);
  EXPECT_FALSE(out.success);  // Landmark (1,5) is not covered.
}

}  // namespace
}  // namespace imca::env
