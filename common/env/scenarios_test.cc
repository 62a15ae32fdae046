// One test per rule of docs/scenarios.md, with scripted action sequences on
// small maps (cells are row * width + col).
#include <algorithm>
#include <array>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "common/env/env.h"
#include "common/env/vec_env.h"
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

// EDTI's Pass and ThreePass as baselines/pass_environment.py and
// three_pass_environment.py state them, ported here from their rules (not
// from our env) as the reference our pass and secret_room must match step by
// step. Coordinates are EDTI's (row, col) on an S x S grid without a border.
class EdtiReference {
 public:
  // three_pass: ThreePass (secret_room); else Pass.
  EdtiReference(int size, bool three_pass, int doi) : S_(size), three_(three_pass), doi_(doi) {
    const int doors = three_ ? 3 : 1;
    open_.assign(doors, false);
    count_.assign(doors, 0);
    if (three_) {
      landmarks_ = {{int(S_ * 0.8), int(S_ * 0.2)}, {int(S_ / 6.0), int(S_ * 0.8)}, {int(S_ / 2.0), int(S_ * 0.8)},
                    {int(S_ / 6.0 * 5), int(S_ * 0.8)}};
    } else {
      landmarks_ = {{int(S_ * 0.8), int(S_ * 0.2)}, {int(S_ * 0.2), int(S_ * 0.8)}};
    }
  }

  // The map value EDTI's code keeps: -1 wall (or closed door), 0 floor, 1 switch.
  bool Blocked(int r, int c) const {
    if (three_ && c >= S_ / 2 && (r == S_ / 3 || r == S_ / 3 * 2)) return true;
    if (c != S_ / 2) return false;
    const int door = DoorAt(r);
    return door < 0 || !open_[door];
  }
  int DoorAt(int r) const {  // Door whose cell (r, S/2) is, or -1.
    if (!three_) return (r >= int(S_ * 0.45) && r < int(S_ * 0.55)) ? 0 : -1;
    for (int m = 0; m < 3; ++m) {
      const int p = int(S_ / 6.0 * (m * 2 + 1));
      if (r == p - 1 || r == p) return m;
    }
    return -1;
  }
  // Landmarks that open door m: Pass either; ThreePass [0, m + 1].
  std::vector<std::array<int, 2>> Opens(int m) const {
    if (!three_) return landmarks_;
    return {landmarks_[0], landmarks_[m + 1]};
  }

  // One step; returns (reward of each agent, done).
  std::pair<int, bool> Step(const int actions[2]) {
    ++t_;
    for (int i = 0; i < 2; ++i) {
      int r = pos_[i][0], c = pos_[i][1];
      switch (actions[i]) {
        case 0: r = std::max(r - 1, 0); break;
        case 1: c = std::min(c + 1, S_ - 1); break;
        case 2: r = std::min(r + 1, S_ - 1); break;
        case 3: c = std::max(c - 1, 0); break;
      }
      if (!Blocked(r, c)) pos_[i] = {r, c};
    }
    for (size_t m = 0; m < open_.size(); ++m) {
      if (open_[m]) {
        if (count_[m] >= doi_) {
          open_[m] = false;
          count_[m] = 0;
        } else {
          ++count_[m];
        }
      }
    }
    for (size_t m = 0; m < open_.size(); ++m) {
      if (open_[m]) continue;
      for (const auto& landmark : Opens(static_cast<int>(m))) {
        for (const auto& p : pos_) {
          if (p == landmark) {
            open_[m] = true;
            count_[m] = 0;
          }
        }
      }
    }
    int past = 0;
    for (const auto& p : pos_) past += p[1] > S_ / 2 && (!three_ || p[0] < S_ / 3);
    const int reward = past >= 2 ? 1000 : 0;
    return {reward, past >= 2 || t_ >= 300};
  }

  int S_;
  bool three_;
  int doi_;
  int t_ = 0;
  std::array<std::array<int, 2>, 2> pos_{};
  std::vector<bool> open_;
  std::vector<int> count_;
  std::vector<std::array<int, 2>> landmarks_;
};

// EDTI's action a is our kEdtiToOurs[a] (EDTI: 0 up, 1 right, 2 down, 3 left).
constexpr int32_t kEdtiToOurs[4] = {kUp, kRight, kDown, kLeft};

struct EdtiTask {
  const char* scenario;
  const char* map;  // Under maps/.
  int size;
  bool three_pass;
};
constexpr EdtiTask kEdtiTasks[] = {{"pass", "pass.txt", 30, false},
                                   {"pass", "pass_fixed_start.txt", 30, false},
                                   {"secret_room", "secret_room.txt", 30, true},
                                   {"secret_room", "secret_room_25.txt", 25, true}};

std::unique_ptr<Scenario> MakeEdti(const EdtiTask& task, int doi) {
  ScenarioConfig config;
  config.name = task.scenario;
  config.map_path = DefaultMapDir() + "/" + task.map;
  config.door_timer = doi;
  auto scenario = MakeScenario(config, DefaultMapDir());
  EXPECT_TRUE(scenario.ok()) << scenario.status();
  return *std::move(scenario);
}

TEST(EdtiTest, MapsAreEdtisLayoutShiftedByTheBorder) {
  for (const EdtiTask& task : kEdtiTasks) {
    auto s = MakeEdti(task, -1);
    const GridMap& map = s->map();
    ASSERT_EQ(map.width(), task.size + 2) << task.map;
    ASSERT_EQ(map.height(), task.size + 2) << task.map;
    EdtiReference ref(task.size, task.three_pass, 8);
    for (int r = -1; r <= task.size; ++r) {
      for (int c = -1; c <= task.size; ++c) {
        const int cell = (r + 1) * map.width() + (c + 1);
        const bool border = r < 0 || c < 0 || r == task.size || c == task.size;
        SCOPED_TRACE(absl::StrCat(task.map, " EDTI (", r, ", ", c, ")"));
        if (border) {
          EXPECT_TRUE(map.IsWall(cell));
          continue;
        }
        const bool door_cell = c == task.size / 2 && ref.DoorAt(r) >= 0;
        EXPECT_EQ(map.IsWall(cell), ref.Blocked(r, c) && !door_cell);
        EXPECT_EQ(map.DoorAt(cell), door_cell ? ref.DoorAt(r) : -1);
        int opens = -1;  // The door a landmark here opens (kEveryDoor: the main switch).
        for (size_t k = 0; k < ref.landmarks_.size(); ++k) {
          if (ref.landmarks_[k] == std::array<int, 2>{r, c}) {
            opens = !task.three_pass ? 0 : (k == 0 ? GridMap::kEveryDoor : static_cast<int>(k) - 1);
          }
        }
        EXPECT_EQ(map.SwitchAt(cell), opens);
      }
    }
    EXPECT_EQ(s->num_actions(), 4);
    EXPECT_EQ(s->step_limit(), 300);
    EXPECT_EQ(s->door_timer(), 8);
    EXPECT_TRUE(s->agents_share_cells());
  }
}

TEST(EdtiTest, StartsAreEdtisResets) {
  // Random starts: each agent anywhere in the left room, independently.
  auto random = MakeEdti(kEdtiTasks[0], -1);
  EXPECT_EQ(random->spawn_pool().size(), 30u * 15u);
  std::vector<int32_t> state(random->state_size());
  Rng rng(5);
  bool shared = false, on_switch = false;
  for (int k = 0; k < 20000; ++k) {
    random->Reset(rng, state.data());
    for (int a = 0; a < 2; ++a) {
      const int r = random->map().Row(state[AgentIndex(a)]) - 1, c = random->map().Col(state[AgentIndex(a)]) - 1;
      ASSERT_TRUE(r >= 0 && r < 30 && c >= 0 && c < 15) << r << "," << c;
      on_switch |= r == 24 && c == 6;
    }
    shared |= state[AgentIndex(0)] == state[AgentIndex(1)];
    EXPECT_FALSE(random->DoorOpen(state.data(), 0)) << "an episode starts with the door closed";
  }
  EXPECT_TRUE(shared) << "independent draws coincide now and then (1 in 450)";
  EXPECT_TRUE(on_switch);
  // --fix_start: both on EDTI's (0, 0).
  auto fixed = MakeEdti(kEdtiTasks[1], 0);
  fixed->Reset(rng, state.data());
  EXPECT_EQ(state[AgentIndex(0)], 1 * 32 + 1);
  EXPECT_EQ(state[AgentIndex(1)], 1 * 32 + 1);
  EXPECT_TRUE(fixed->ValidateState(state.data()).ok());
}

// Our pass and secret_room against the reference over random play that starts
// the agents on and around the switches and doors, where the rules act.
TEST(EdtiTest, StepByStepLikeEdtisCode) {
  for (const EdtiTask& task : kEdtiTasks) {
    for (int doi : {0, 1, 8}) {
      auto s = MakeEdti(task, doi);
      const GridMap& map = s->map();
      const int S = task.size;
      Rng rng(17);
      int64_t opened = 0, successes = 0, steps = 0;
      for (int episode = 0; episode < 300; ++episode) {
        EdtiReference ref(S, task.three_pass, doi);
        std::vector<int32_t> state(s->state_size(), 0);
        // Starts near a landmark or a door (EDTI's reset draws from the left
        // room; these reach the rules' corner cases far more often).
        std::vector<std::array<int, 2>> spots = ref.landmarks_;
        for (int r = 0; r < S; ++r) {
          if (ref.DoorAt(r) >= 0) spots.push_back({r, S / 2 + (episode % 2 ? 1 : -1)});
        }
        for (int a = 0; a < 2; ++a) {
          std::array<int, 2> p = spots[rng.Uniform(static_cast<uint32_t>(spots.size()))];
          ref.pos_[a] = p;
          state[AgentIndex(a)] = (p[0] + 1) * map.width() + (p[1] + 1);
        }
        ASSERT_TRUE(s->ValidateState(state.data()).ok());
        std::vector<float> rewards(2);
        for (int t = 1; t <= 300; ++t) {
          int edti[2];
          int32_t ours[2];
          for (int a = 0; a < 2; ++a) {
            edti[a] = static_cast<int>(rng.Uniform(4));
            ours[a] = kEdtiToOurs[edti[a]];
          }
          const auto [reward, done] = ref.Step(edti);
          const StepOutcome out = s->Step(state.data(), ours, rng, rewards.data());
          ++steps;
          SCOPED_TRACE(absl::StrCat(task.map, " doi ", doi, " episode ", episode, " t ", t));
          for (int a = 0; a < 2; ++a) {
            ASSERT_EQ(map.Row(state[AgentIndex(a)]) - 1, ref.pos_[a][0]);
            ASSERT_EQ(map.Col(state[AgentIndex(a)]) - 1, ref.pos_[a][1]);
            ASSERT_FLOAT_EQ(rewards[a], static_cast<float>(reward));
          }
          for (size_t m = 0; m < ref.open_.size(); ++m) {
            ASSERT_EQ(s->DoorOpen(state.data(), static_cast<int>(m)), ref.open_[m]) << "door " << m;
            opened += ref.open_[m];
          }
          ASSERT_EQ(out.terminated || out.truncated, done);
          ASSERT_EQ(out.success, reward > 0);
          ASSERT_TRUE(s->ValidateState(state.data()).ok());
          successes += out.success;
          if (done) break;
        }
      }
      // The rules were exercised, not just walked past.
      EXPECT_GT(opened, 100) << task.map << " doi " << doi << " over " << steps << " steps";
      EXPECT_GT(successes, 0) << task.map << " doi " << doi;
    }
  }
}

// Scripted: agent 1 steps onto the left switch and off again at once; agent 2
// waits at the door (put back each move) and tries to pass on move k after
// the opening.
TEST(EdtiTest, DoorPassesForExactlyDoiPlusOneMovesAfterItOpens) {
  for (int doi : {0, 8}) {
    auto s = MakeEdti(kEdtiTasks[0], doi);
    const int W = s->map().width();
    auto cell = [W](int r, int c) { return (r + 1) * W + (c + 1); };  // EDTI coordinates.
    for (int k = 1; k <= doi + 2; ++k) {
      Episode ep{*s, std::vector<int32_t>(s->state_size(), 0)};
      ep.state[AgentIndex(0)] = cell(24, 5);   // Left of the switch (24, 6).
      ep.state[AgentIndex(1)] = cell(14, 14);  // Left of the door cell (14, 15).
      ep.Step({kRight, kRight});  // Agent 1 onto the switch; agent 2 bumps the closed door.
      ASSERT_EQ(ep.cell(1), cell(14, 14));
      ASSERT_TRUE(s->DoorOpen(ep.state.data(), 0)) << "opens after the move onto the switch";
      for (int j = 1; j < k; ++j) {
        ep.Step({kLeft, kLeft});  // Agent 1 walks away from the switch.
        ep.state[AgentIndex(1)] = cell(14, 14);
      }
      ep.Step({kLeft, kRight});  // Move k after the opening.
      EXPECT_EQ(ep.cell(1) == cell(14, 15), k <= doi + 1) << "doi " << doi << " move " << k;
    }
  }
}

TEST(EdtiTest, AgentsShareCellsAndMoveIndependently) {
  auto s = MakeEdti(kEdtiTasks[1], 0);
  Episode ep{*s, std::vector<int32_t>(s->state_size(), 0)};
  Rng rng(1);
  s->Reset(rng, ep.state.data());
  const int start = ep.cell(0);
  ASSERT_EQ(ep.cell(1), start);
  ep.Step({kRight, kRight});  // Both into the same cell.
  EXPECT_EQ(ep.cell(0), start + 1);
  EXPECT_EQ(ep.cell(1), start + 1);
  ep.Step({kLeft, kDown});  // Apart again; a move into the border fails like EDTI's clamp.
  ep.Step({kLeft, kUp});
  EXPECT_EQ(ep.cell(0), start);
  EXPECT_EQ(ep.cell(1), start + 1);
  ep.Step({kRight, kLeft});  // A swap is two independent moves.
  EXPECT_EQ(ep.cell(0), start + 1);
  EXPECT_EQ(ep.cell(1), start);
}

TEST(EdtiTest, MainSwitchOpensEveryDoorAndRoomSwitchesTheirOwn) {
  for (int task : {2, 3}) {
    auto s = MakeEdti(kEdtiTasks[task], 8);
    const GridMap& map = s->map();
    std::vector<int32_t> main_switch, room_switch(3, -1);
    for (int cell = 0; cell < map.num_cells(); ++cell) {
      if (map.SwitchAt(cell) == GridMap::kEveryDoor) main_switch.push_back(cell);
      if (map.SwitchAt(cell) >= 0 && map.SwitchAt(cell) < 3) room_switch[map.SwitchAt(cell)] = cell;
    }
    ASSERT_EQ(main_switch.size(), 1u);
    for (int d = 0; d < 3; ++d) EXPECT_EQ(map.switches(d).size(), 2u) << "its own and the main switch";
    // On the main switch after a move: all three doors open.
    Episode ep{*s, std::vector<int32_t>(s->state_size(), 0)};
    ep.state[AgentIndex(0)] = main_switch[0] - 1;
    ep.state[AgentIndex(1)] = main_switch[0] - 1;
    ep.Step({kRight, kLeft});
    for (int d = 0; d < 3; ++d) EXPECT_TRUE(s->DoorOpen(ep.state.data(), d)) << kEdtiTasks[task].map << " " << d;
    // A room switch opens its own door only.
    for (int d = 0; d < 3; ++d) {
      Episode room{*s, std::vector<int32_t>(s->state_size(), 0)};
      room.state[AgentIndex(0)] = room_switch[d] - 1;
      room.state[AgentIndex(1)] = room_switch[d] - 1;
      room.Step({kRight, kLeft});
      for (int e = 0; e < 3; ++e) EXPECT_EQ(s->DoorOpen(room.state.data(), e), e == d) << d << " " << e;
    }
  }
}

TEST(EdtiTest, DoorTimerIsValidated) {
  ScenarioConfig config;
  config.name = "pass";
  for (int bad : {-2, 31}) {
    config.door_timer = bad;
    auto s = MakeScenario(config, DefaultMapDir());
    ASSERT_FALSE(s.ok());
    EXPECT_THAT(s.status().message(), ::testing::HasSubstr("door_timer"));
  }
  config.name = "coop_nav";
  config.door_timer = 3;
  auto s = MakeScenario(config, DefaultMapDir());
  ASSERT_FALSE(s.ok());
  EXPECT_THAT(s.status().message(), ::testing::HasSubstr("door_timer is for the timed door scenarios"));
  // '@' needs agents that may share a cell.
  auto shared = Make("pass", "#@.#a.A.G#\n");
  EXPECT_TRUE(shared->agents_share_cells());
  auto map = GridMap::Parse("#@.#a.A.GT#\n", "at.txt");
  ASSERT_TRUE(map.ok());
  ScenarioConfig rooms;
  rooms.name = "multi_room";
  auto refused = MakeScenarioWithMap(rooms, *map);
  ASSERT_FALSE(refused.ok());
  EXPECT_THAT(refused.status().message(), ::testing::HasSubstr("cannot share a cell"));
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
