// CMAE's parts worked by hand, its policy as actors read it, and the whole
// algorithm solving a small two-agent room task.
#include "learner/algorithms/cmae/cmae.h"

#include <cmath>
#include <filesystem>
#include <memory>
#include <vector>

#include "common/env/env.h"
#include "common/env/grid_map.h"
#include "common/env/joint_state.h"
#include "common/env/vec_env.h"
#include "common/protocol/policy_mlp.h"
#include "common/protocol/policy_table.h"
#include "common/protocol/test_unrolls.h"
#include "gtest/gtest.h"
#include "learner/algorithms/cmae/cmae_parts.h"
#include "learner/algorithms/registry.h"
#include "learner/learner.h"

namespace imca::learner {
namespace {

using cmae::QTable;
using cmae::Replay;
using cmae::Subspaces;
using cmae::Transition;

// ---- Subspaces: entropy, ranks, the choice and the goal ----

TEST(CmaeSubspacesTest, NormalisedEntropyOfHandCounts) {
  // Two variables of ranges 2 and 3, 2 joint actions. Var 0's counter gets
  // (0, a0) three times and (1, a1) once: H = -(3/4 ln 3/4 + 1/4 ln 1/4) over
  // ln(2 x 2).
  Subspaces s({2, 3}, 2, 10, 50, 20);
  const int32_t v00[] = {0, 0}, v12[] = {1, 2};
  for (int i = 0; i < 3; ++i) s.Count(v00, 0);
  s.Count(v12, 1);
  const double h = -(0.75 * std::log(0.75) + 0.25 * std::log(0.25));
  EXPECT_NEAR(s.NormalisedEntropy(0b01), h / std::log(4.0), 1e-12);
  // Var 1 saw values 0 three times and 2 once: the same shape over 3 x 2.
  EXPECT_NEAR(s.NormalisedEntropy(0b10), h / std::log(6.0), 1e-12);
  EXPECT_EQ(s.CountOf(0b01, v00, 0), 3u);
  EXPECT_EQ(s.CountOf(0b01, v12, 0), 0u);
}

TEST(CmaeSubspacesTest, RanksAreItertoolsCombinationsOrder) {
  Subspaces s({2, 2, 2, 2, 2}, 4, 10, 50, 20);
  EXPECT_EQ(s.Rank(0b00001), 0);  // (0,)
  EXPECT_EQ(s.Rank(0b10000), 4);  // (4,)
  EXPECT_EQ(s.Rank(0b00011), 0);  // (0, 1)
  EXPECT_EQ(s.Rank(0b00101), 1);  // (0, 2)
  EXPECT_EQ(s.Rank(0b00110), 4);  // (1, 2): after (0,1) (0,2) (0,3) (0,4)
  EXPECT_EQ(s.Rank(0b11000), 9);  // (3, 4): the last of 10
  EXPECT_EQ(s.Rank(0b00111), 0);  // (0, 1, 2)
  EXPECT_EQ(s.Rank(0b11100), 9);  // (2, 3, 4): the last of 10
  EXPECT_EQ(s.Rank(0b11111), 0);
}

TEST(CmaeSubspacesTest, ChoiceWeighsExpMinusRecipTTimesEntropyAndGrowsTheTree) {
  // Var 0 spread evenly (entropy 1 over its 2 values x 1 action), var 1
  // always 0 (entropy 0): weights exp(-50) : 1, so var 1 is chosen and its
  // superset {0, 1} gets a counter filled from the replay and is tracked.
  Subspaces s({2, 2}, 1, 10, 50, 20);
  const int32_t a[] = {0, 0}, b[] = {1, 0};
  s.Count(a, 0);
  s.Count(b, 0);
  EXPECT_NEAR(s.NormalisedEntropy(0b01), 1.0, 1e-12);
  EXPECT_NEAR(s.NormalisedEntropy(0b10), 0.0, 1e-12);
  Rng rng(7);
  int replayed = 0;
  auto replay = [&](const std::function<void(const int32_t*, int64_t)>& visit) {
    visit(a, 0);
    visit(b, 0);
    visit(b, 0);
    replayed += 3;
  };
  const auto weights = s.Reselect(replay, rng);
  ASSERT_EQ(weights.size(), 2u);
  // Taken off the queue in (entropy, level, rank) order: both at 0, var 0 first.
  EXPECT_EQ(weights[0].first, 0b01u);
  EXPECT_NEAR(weights[0].second, std::exp(-50.0) / (1 + std::exp(-50.0)), 1e-30);
  EXPECT_NEAR(weights[1].second, 1 / (1 + std::exp(-50.0)), 1e-15);
  EXPECT_EQ(s.chosen(), 0b10u);
  EXPECT_TRUE(s.has_counter(0b11));
  EXPECT_EQ(replayed, 3);
  EXPECT_EQ(s.CountOf(0b11, b, 0), 2u);
  EXPECT_EQ(s.tracked(), (std::vector<Subspaces::Mask>{0b01, 0b10, 0b11}));
  // The new counter counts from now on.
  s.Count(b, 0);
  EXPECT_EQ(s.CountOf(0b11, b, 0), 3u);
}

TEST(CmaeSubspacesTest, GoalIsTheLeastCountedSampledPair) {
  // Var 0 (range 2) is the chosen space at the start; 2 joint actions.
  // Counts: (0,a0)=3 (0,a1)=2 (1,a0)=5 (1,a1)=1: the goal is (state with
  // var 0 = 1, a1), whichever sample holds it.
  Subspaces s({2, 3}, 2, 10, 50, 1000);
  const int32_t zero[] = {0, 1}, one[] = {1, 2};
  for (int i = 0; i < 3; ++i) s.Count(zero, 0);
  for (int i = 0; i < 2; ++i) s.Count(zero, 1);
  for (int i = 0; i < 5; ++i) s.Count(one, 0);
  s.Count(one, 1);
  const std::vector<const int32_t*> samples = {zero, zero, one, zero};
  Rng rng(3);
  auto none = [](const std::function<void(const int32_t*, int64_t)>&) {};
  const auto goal = s.Goal(static_cast<int>(samples.size()),
                           [&](int i, int32_t* vars) { vars[0] = samples[i][0], vars[1] = samples[i][1]; }, none, rng);
  ASSERT_TRUE(goal.has_value());
  EXPECT_EQ(goal->first, 2);
  EXPECT_EQ(goal->second, 1);
  // Ties are drawn among: with only var-0 = 0 states sampled, (0, a1) wins.
  const auto other = s.Goal(2, [&](int, int32_t* vars) { vars[0] = 0, vars[1] = 0; }, none, rng);
  ASSERT_TRUE(other.has_value());
  EXPECT_EQ(other->second, 1);
}

// ---- Replay and Q-tables ----

TEST(CmaeReplayTest, GoalTrajectoryIsTheEpisodeIntoTheFirstSlotOfTheGoal) {
  Replay replay(16);
  // Episode 1: states 10 -> 11 -> 12 -> done; episode 2: 10 -> 12 -> 13 (reward) done.
  replay.Insert({10, 11, 0, 0, false});
  replay.Insert({11, 12, 1, 0, false});
  replay.Insert({12, 13, 2, 0, true});
  replay.Insert({10, 12, 3, 0, false});
  replay.Insert({12, 13, 1, 1, true});
  EXPECT_EQ(replay.time_stamp(2), 2);
  EXPECT_EQ(replay.time_stamp(3), 0);
  const auto into_12 = replay.GoalTrajectory(12);
  ASSERT_TRUE(into_12.has_value());
  EXPECT_EQ(into_12->second, 2);  // The first slot holding 12.
  EXPECT_EQ(into_12->first, (std::vector<int64_t>{0, 1}));
  EXPECT_FALSE(replay.GoalTrajectory(99).has_value());
  // The prioritised batch: the first rewarded slot, back to its episode's start.
  Rng rng(1);
  EXPECT_EQ(replay.PrioritizedBatch(2, rng), (std::vector<int64_t>{4, 3}));
  const std::vector<int64_t> batch = replay.PrioritizedBatch(6, rng);
  ASSERT_EQ(batch.size(), 6u);
  for (int64_t slot : batch) EXPECT_LT(slot, 5);
}

TEST(CmaeReplayTest, TheRingWrapsAndForgetsOverwrittenSlots) {
  Replay replay(4);
  for (int i = 0; i < 6; ++i) replay.Insert({100 + i, 101 + i, 0, i == 5 ? 1.0 : 0.0, i == 5});
  EXPECT_EQ(replay.size(), 4);
  EXPECT_FALSE(replay.GoalTrajectory(100).has_value());  // Overwritten.
  const auto into = replay.GoalTrajectory(105);           // Slot 1, time stamp 5: wraps back over the ring.
  ASSERT_TRUE(into.has_value());
  EXPECT_EQ(into->second, 1);
  EXPECT_EQ(into->first.size(), 5u);
  EXPECT_EQ(into->first.back(), 0);
  Rng rng(2);
  const std::vector<int64_t> distinct = replay.SampleDistinct(10, rng);
  EXPECT_EQ(distinct.size(), 4u);
  EXPECT_EQ(std::set<int64_t>(distinct.begin(), distinct.end()).size(), 4u);
}

TEST(CmaeQTableTest, UpdateIsCmaesRule) {
  QTable q(4);
  q.Update(5, 2, 1, 5, /*done=*/true, 0.1, 0.95);
  EXPECT_DOUBLE_EQ(q.Value(5, 2), 0.1);
  q.Update(4, 1, 0, 5, /*done=*/false, 0.1, 0.95);
  EXPECT_DOUBLE_EQ(q.Value(4, 1), 0.1 * 0.95 * 0.1);
  q.Update(5, 2, 1, 5, /*done=*/true, 0.1, 0.95);
  EXPECT_DOUBLE_EQ(q.Value(5, 2), 0.9 * 0.1 + 0.1);
  EXPECT_EQ(q.NonzeroStates(), (std::vector<int64_t>{4, 5}));
  EXPECT_EQ(q.Max(77), 0);
}

// ---- The policy actors act with ----

v1::Policy TablePolicy(const env::Scenario& scenario, int64_t state, std::vector<double> explore,
                       std::vector<double> exploit, double weight) {
  const auto space = env::JointStateSpace::Create(scenario);
  v1::Policy p;
  p.set_version(3);
  p.set_architecture(v1::Policy::TABULAR_Q);
  p.set_num_actions(scenario.num_actions());
  v1::TabularPolicy* t = p.mutable_tabular();
  t->set_num_agents(scenario.num_agents());
  t->set_joint_states(space->size());
  t->set_exploit_weight(weight);
  t->mutable_explore()->add_states(state);
  for (double v : explore) t->mutable_explore()->add_values(v);
  t->mutable_exploit()->add_states(state);
  for (double v : exploit) t->mutable_exploit()->add_values(v);
  return p;
}

std::unique_ptr<env::Scenario> PassCmae() {
  env::ScenarioConfig config;
  config.name = "pass_cmae";
  return *env::MakeScenario(config, env::DefaultMapDir());
}

TEST(CmaePolicyTableTest, ActsGreedilyOnTheMixAndEvaluatesOnExploitation) {
  const auto scenario = PassCmae();
  env::VecEnv envs(scenario.get(), 1, 1);
  const auto space = env::JointStateSpace::Create(*scenario);
  const int64_t s = space->Index(envs.states());
  // Agent 1: explore favours action 0, exploit action 1; agent 2: all tie.
  const std::vector<double> explore = {0.1, 0, 0, 0, 0, 0, 0, 0}, exploit = {0, 0.2, 0, 0, 0, 0, 0, 0};
  float probs[8];
  auto table = PolicyTable::FromProto(TablePolicy(*scenario, s, explore, exploit, 0.25), *scenario);
  ASSERT_TRUE(table.ok()) << table.status();
  table->Probabilities(envs.states(), 1, /*evaluation=*/false, probs);
  EXPECT_EQ(std::vector<float>(probs, probs + 4), (std::vector<float>{1, 0, 0, 0}));  // 0.075 > 0.05
  EXPECT_EQ(std::vector<float>(probs + 4, probs + 8), (std::vector<float>(4, 0.25f)));
  table->Probabilities(envs.states(), 1, /*evaluation=*/true, probs);
  EXPECT_EQ(std::vector<float>(probs, probs + 4), (std::vector<float>{0, 1, 0, 0}));
  table = PolicyTable::FromProto(TablePolicy(*scenario, s, explore, exploit, 0.75), *scenario);
  table->Probabilities(envs.states(), 1, /*evaluation=*/false, probs);
  EXPECT_EQ(std::vector<float>(probs, probs + 4), (std::vector<float>{0, 1, 0, 0}));  // 0.025 < 0.15
  // Ties share: explore 0.1 on actions 0 and 2 at weight 0.
  table = PolicyTable::FromProto(TablePolicy(*scenario, s, {0.1, 0, 0.1, 0, 0, 0, 0, 0}, exploit, 0), *scenario);
  table->Probabilities(envs.states(), 1, /*evaluation=*/false, probs);
  EXPECT_EQ(std::vector<float>(probs, probs + 4), (std::vector<float>{0.5, 0, 0.5, 0}));
}

TEST(CmaePolicyTableTest, RefusesWhatDoesNotFit) {
  const auto scenario = PassCmae();
  v1::Policy p = TablePolicy(*scenario, 5, std::vector<double>(8, 0), std::vector<double>(8, 0), 0.5);
  p.mutable_tabular()->mutable_exploit()->add_values(1);
  EXPECT_TRUE(absl::IsInvalidArgument(PolicyTable::FromProto(p, *scenario).status()));
  p = TablePolicy(*scenario, 5, std::vector<double>(8, 0), std::vector<double>(8, 0), 1.5);
  EXPECT_TRUE(absl::IsInvalidArgument(PolicyTable::FromProto(p, *scenario).status()));
  p = TablePolicy(*scenario, -1, std::vector<double>(8, 0), std::vector<double>(8, 0), 0.5);
  EXPECT_TRUE(absl::IsInvalidArgument(PolicyTable::FromProto(p, *scenario).status()));
  p = TablePolicy(*scenario, 5, std::vector<double>(8, 0), std::vector<double>(8, 0), 0.5);
  p.mutable_tabular()->set_joint_states(17);
  EXPECT_TRUE(absl::IsInvalidArgument(PolicyTable::FromProto(p, *scenario).status()));
}

// ---- The whole algorithm ----

// Plays one episode of env 0 with `table` (on its exploitation side with
// `evaluation`), recording it into `u` if given; returns its success.
bool PlayEpisode(const PolicyTable& table, env::VecEnv& envs, bool evaluation, Rng& rng, v1::Unroll* u) {
  const env::Scenario& scenario = envs.scenario();
  const int n = scenario.num_agents(), K = scenario.state_size(), A = scenario.num_actions();
  std::vector<int32_t> actions(n), reached(K);
  std::vector<float> rewards(n), probs(n * A);
  bool terminated = false, truncated = false;
  do {
    if (u != nullptr) {
      u->mutable_states()->Add(envs.states(), envs.states() + K);
      u->add_episode_ids(envs.episode_id(0));
    }
    table.Probabilities(envs.states(), 1, evaluation, probs.data());
    for (int a = 0; a < n; ++a) actions[a] = SampleCategorical(&probs[a * A], A, rng.UniformDouble());
    envs.Step(actions.data(), rewards.data(), &terminated, &truncated, reached.data());
    if (u != nullptr) {
      u->mutable_actions()->Add(actions.begin(), actions.end());
      u->mutable_action_probs()->Add(probs.begin(), probs.end());
      u->mutable_rewards()->Add(rewards.begin(), rewards.end());
      u->mutable_next_states()->Add(reached.begin(), reached.end());
      u->add_terminated(terminated);
      u->add_truncated(truncated);
      u->set_length(u->length() + 1);
    }
  } while (!terminated && !truncated);
  if (u != nullptr) u->mutable_states()->Add(envs.states(), envs.states() + K);
  std::vector<env::EpisodeEnd> ends;
  envs.TakeFinished(&ends);
  return !ends.empty() && ends.back().success;
}

// One episode of env 0 acted with the algorithm's exported policy, as an
// actor sends it: one unroll of the whole episode (CMAE's loop).
void PlayUnroll(const Cmae& cmae, env::VecEnv& envs, int64_t version, Rng& rng, FeaturisedUnroll* f) {
  const env::Scenario& scenario = envs.scenario();
  const auto table = PolicyTable::FromProto(cmae.ExportPolicy(version), scenario);
  ASSERT_TRUE(table.ok()) << table.status();
  v1::Unroll& u = f->unroll;
  u.set_actor_id("a");
  u.set_incarnation(1);
  u.set_num_envs(1);
  u.set_num_agents(scenario.num_agents());
  u.set_num_actions(scenario.num_actions());
  u.set_state_size(scenario.state_size());
  PlayEpisode(*table, envs, /*evaluation=*/false, rng, &u);
}

// Acts and trains on `episodes` episodes of one env.
void Train(Cmae& cmae, env::VecEnv& envs, int episodes, Rng& rng) {
  for (int episode = 0; episode < episodes; ++episode) {
    FeaturisedUnroll f;
    PlayUnroll(cmae, envs, episode, rng, &f);
    ASSERT_TRUE(cmae.Add(f).ok());
    ASSERT_TRUE(cmae.Train().ok());
  }
}

// Success share of `episodes` evaluation episodes (the exploitation tables).
double Evaluate(const Cmae& cmae, const env::Scenario& scenario, int episodes, uint64_t seed) {
  env::VecEnv envs(&scenario, 1, seed);
  Rng rng(seed);
  const auto table = PolicyTable::FromProto(cmae.ExportPolicy(0), scenario);
  int successes = 0;
  for (int episode = 0; episode < episodes; ++episode) {
    successes += PlayEpisode(*table, envs, /*evaluation=*/true, rng, nullptr);
  }
  return static_cast<double>(successes) / episodes;
}

// A small pass_cmae: 7 x 3 cells left of the wall at column 16, 2 x 3 right
// of it; the door 'A' opens while an agent is within 4.5 of a switch 'a'
// (the left one is too far from the door for its holder to pass).
std::unique_ptr<env::Scenario> SmallPass(int step_limit) {
  const auto map = env::GridMap::Parse(
      "####################\n"
      "#########.......A..#\n"
      "#########.12....#..#\n"
      "#########a......#.a#\n"
      "####################\n",
      "small pass");
  EXPECT_TRUE(map.ok()) << map.status();
  env::ScenarioConfig config;
  config.name = "pass_cmae";
  config.step_limit = step_limit;
  auto scenario = env::MakeScenarioWithMap(config, *map);
  EXPECT_TRUE(scenario.ok()) << scenario.status();
  return *std::move(scenario);
}

LearnerConfig SmallConfig(int64_t episodes) {
  LearnerConfig config = *DefaultLearnerConfig("pass_cmae", "cmae");
  MutableOptions<CmaeConfig>(&config).total_episodes = episodes;
  config.seed = 5;
  return config;
}

TEST(CmaeTest, ExplorationTableIsFittedOnTheWayIntoTheGoal) {
  const auto scenario = SmallPass(40);
  auto cmae = Cmae::Create(scenario.get(), SmallConfig(100));
  ASSERT_TRUE(cmae.ok()) << cmae.status();
  env::VecEnv envs(scenario.get(), 1, 9);
  Rng rng(9);
  Train(**cmae, envs, 3, rng);
  const auto [goal_state, goal_action] = (*cmae)->goal();
  ASSERT_GE(goal_state, 0);
  const auto trajectory = (*cmae)->replay().GoalTrajectory(goal_state);
  ASSERT_TRUE(trajectory.has_value());
  const env::JointStateSpace& space = (*cmae)->space();
  for (int k = 0; k < 2; ++k) {
    const QTable& q = (*cmae)->explore(k);
    const int goal_k = space.AgentAction(goal_action, k);
    // The goal pair: lr * 1 from the terminal goal transition.
    EXPECT_DOUBLE_EQ(q.Value(goal_state, goal_k), 0.1);
    // Walking back: lr * gamma * max Q(next), from the goal on.
    const std::vector<int64_t>& before = trajectory->first;
    double next_max = 0.1;
    int checked = 0;
    for (auto it = before.rbegin(); it != before.rend() && checked < 3; ++it, ++checked) {
      const Transition& t = (*cmae)->replay().at(*it);
      if (t.state == goal_state) break;
      const double expected = 0.1 * 0.95 * next_max;
      EXPECT_NEAR(q.Max(t.state), std::max(expected, q.Max(t.state)), 1e-15);
      EXPECT_NEAR(q.Value(t.state, space.AgentAction(t.joint_action, k)), expected, 1e-12 * expected + 1e-300)
          << "agent " << k << " step back " << checked;
      next_max = q.Max(t.state);
    }
    // Nothing else: the table holds the goal and its way in only.
    EXPECT_LE(q.rows(), static_cast<int64_t>(before.size()) + 1);
  }
}

TEST(CmaeTest, ExploitationWeightRisesWithEpisodesAndSaveLoadGoesOnExactly) {
  const auto scenario = SmallPass(30);
  auto a = Cmae::Create(scenario.get(), SmallConfig(8));
  ASSERT_TRUE(a.ok());
  env::VecEnv envs(scenario.get(), 1, 4);
  Rng rng(4);
  Train(**a, envs, 2, rng);
  EXPECT_EQ((*a)->episodes(), 2);
  EXPECT_DOUBLE_EQ((*a)->exploit_weight(), 0.25);
  EXPECT_DOUBLE_EQ((*a)->ExportPolicy(1).tabular().exploit_weight(), 0.25);
  const std::string path = ::testing::TempDir() + "/cmae_state";
  ASSERT_TRUE((*a)->Save(path).ok());
  auto b = Cmae::Create(scenario.get(), SmallConfig(8));
  ASSERT_TRUE((*b)->Load(path).ok());
  // Both go on from the same environment state: equal policies after.
  env::VecEnv envs_b = envs;
  Rng rng_b = rng;
  Train(**a, envs, 10, rng);
  Train(**b, envs_b, 10, rng_b);
  EXPECT_EQ((*a)->ExportPolicy(5).SerializeAsString(), (*b)->ExportPolicy(5).SerializeAsString());
  EXPECT_DOUBLE_EQ((*b)->exploit_weight(), 1.0);
  // A checkpoint of another scenario's tables is refused, the state kept.
  const auto other = PassCmae();
  auto c = Cmae::Create(other.get(), SmallConfig(8));
  EXPECT_TRUE(absl::IsInvalidArgument((*c)->Load(path)));
  std::filesystem::resize_file(path, 100);
  EXPECT_FALSE((*b)->Load(path).ok());
  EXPECT_EQ((*b)->episodes(), 12);
}

TEST(CmaeTest, ABrokenEpisodeLosesThePartBeforeTheBreak) {
  const auto scenario = SmallPass(20);
  auto cmae = Cmae::Create(scenario.get(), SmallConfig(100));
  ASSERT_TRUE(cmae.ok());
  // 10 steps of an episode, then the actor restarts (a new incarnation)
  // and plays a whole 20-step episode: only that one is counted and stored.
  FeaturisedUnroll first, second;
  first.unroll = testing::RandomUnroll(*scenario, 10, 1, 1);
  first.unroll.set_incarnation(1);
  second.unroll = testing::RandomUnroll(*scenario, 20, 1, 2);
  second.unroll.set_incarnation(2);
  ASSERT_TRUE((*cmae)->Add(first).ok());
  EXPECT_EQ((*cmae)->replay().size(), 0);
  ASSERT_TRUE((*cmae)->Add(second).ok());
  EXPECT_EQ((*cmae)->episodes(), 1);
  EXPECT_EQ((*cmae)->replay().size(), 20);
  // A single variable's counter holds those 20 steps and no more.
  int64_t counted = 0;
  std::vector<int32_t> vars((*cmae)->space().num_vars());
  for (int64_t slot = 0; slot < 20; ++slot) {
    (*cmae)->space().Decode((*cmae)->replay().at(slot).state, vars.data());
    counted = std::max<int64_t>(counted, (*cmae)->subspaces().CountOf(0b1, vars.data(),
                                                                      (*cmae)->replay().at(slot).joint_action));
  }
  EXPECT_GE(counted, 1);
  EXPECT_LE(counted, 20);
}

TEST(CmaeTest, ReportsTheEntropyTheActorsActedWith) {
  // Untrained, every action ties: ln 4 per agent-step; after training the
  // greedy tables break most ties.
  const auto scenario = SmallPass(40);
  auto cmae = Cmae::Create(scenario.get(), SmallConfig(300));
  ASSERT_TRUE(cmae.ok());
  env::VecEnv envs(scenario.get(), 1, 11);
  Rng rng(11);
  auto played = [&]() {
    FeaturisedUnroll f;
    PlayUnroll(**cmae, envs, 0, rng, &f);
    EXPECT_TRUE((*cmae)->Add(f).ok());
    return (*cmae)->Train()->entropy;
  };
  EXPECT_NEAR(played(), std::log(4.0), 1e-6);
  Train(**cmae, envs, 300, rng);
  EXPECT_LT(played(), 0.5 * std::log(4.0));
}

TEST(CmaeTest, RefusesWhatItCannotHold) {
  env::ScenarioConfig config;
  config.name = "coop_nav";
  config.num_agents = 9;
  auto big = env::MakeScenario(config, env::DefaultMapDir());
  ASSERT_TRUE(big.ok()) << big.status();
  LearnerConfig learner = *DefaultLearnerConfig("coop_nav", "cmae");
  const auto refused = Cmae::Create(big->get(), learner);
  ASSERT_TRUE(absl::IsInvalidArgument(refused.status()));
  EXPECT_NE(refused.status().message().find("2^62"), std::string::npos) << refused.status();
  const auto scenario = PassCmae();
  MutableOptions<CmaeConfig>(&learner).max_table_mb = 10;
  const auto over = Cmae::Create(scenario.get(), learner);
  ASSERT_TRUE(absl::IsInvalidArgument(over.status()));
  EXPECT_NE(over.status().message().find("--cmae_max_table_mb"), std::string::npos) << over.status();
}

TEST(CmaeTest, SolvesASmallTwoAgentRoomTask) {
  // One agent must hold a switch while the other passes the door, then the
  // other way round, both in the right room at once: 40 steps an episode.
  const auto scenario = SmallPass(40);
  auto cmae = Cmae::Create(scenario.get(), SmallConfig(300));
  ASSERT_TRUE(cmae.ok());
  // Untrained, the evaluation policy is uniformly random: it rarely succeeds.
  EXPECT_LE(Evaluate(**cmae, *scenario, 20, 99), 0.3);
  env::VecEnv envs(scenario.get(), 1, 11);
  Rng rng(11);
  Train(**cmae, envs, 300, rng);
  EXPECT_GE(Evaluate(**cmae, *scenario, 20, 99), 0.9);
}

}  // namespace
}  // namespace imca::learner
