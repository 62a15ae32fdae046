// The task versions of CMAE and MACE (docs/scenarios.md, "The task versions
// of CMAE and MACE") against ports of the released code's step rules
// (CMAE's env/rooms.py, env/secret_rooms.py, env/push_box.py; MACE's
// src/envs/grid_world/room.py, secret_rooms.py), written here from those rules and not from our env: every
// step of random play from states near the switches, doors and box must give
// the same positions, walls, doors, reward and end.
#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "common/env/env.h"
#include "gtest/gtest.h"

namespace imca::env {
namespace {

// A reference grid without a border, cells (row, col); row = CMAE's y and
// MACE's x. wall[row][col] is the code's wall_map (doors included while shut).
class Reference {
 public:
  explicit Reference(int size) : S(size), wall(size, std::vector<int>(size, 0)) {}
  virtual ~Reference() = default;
  // One step with actions in the code's numbering (0 up, 1 down, 2 left,
  // 3 right: the same in CMAE and MACE, and ours); returns (reward, done).
  virtual std::pair<double, bool> Step(const std::vector<int>& actions) = 0;
  virtual std::vector<bool> Doors() const = 0;  // Our door order.

  void Move(std::array<int, 2>& p, int action) const {
    const int r = p[0], c = p[1];
    if (action == 0 && r > 0 && !wall[r - 1][c]) --p[0];
    if (action == 1 && r < S - 1 && !wall[r + 1][c]) ++p[0];
    if (action == 2 && c > 0 && !wall[r][c - 1]) --p[1];
    if (action == 3 && c < S - 1 && !wall[r][c + 1]) ++p[1];
  }
  static double Dist(const std::array<int, 2>& a, const std::array<int, 2>& b) {
    return std::sqrt(static_cast<double>((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1])));
  }

  int S;
  int t = 0;
  std::vector<std::vector<int>> wall;
  std::vector<std::array<int, 2>> pos;
};

// CMAE rooms.py (room30): one door at x = S/2, rows S/2 -+ S/10; switches
// (x, y) = (S/10, 0.8S) and (0.8S, S/10); active within 1.5 * S/10.
class CmaeRooms : public Reference {
 public:
  CmaeRooms() : Reference(30) {
    for (int r = 0; r < S; ++r) wall[r][S / 2] = 1;
    pos = {{4, 4}, {3, 3}};
    switches_ = {{24, 3}, {3, 24}};  // (row, col) of CMAE's (3, 24) and (24, 3).
  }
  std::pair<double, bool> Step(const std::vector<int>& actions) override {
    for (int i = 0; i < 2; ++i) Move(pos[i], actions[i]);
    const int radius = S / 10;
    open_ = false;
    for (const auto& sw : switches_) {
      for (const auto& p : pos) open_ |= Dist(p, sw) <= 1.5 * radius;
    }
    for (int r = S / 2 - radius; r <= S / 2 + radius; ++r) wall[r][S / 2] = open_ ? 0 : 1;
    ++t;
    bool in = true;
    for (const auto& p : pos) in &= !(p[1] < S / 2.0 + 1);
    const double reward = in ? 1 : 0;
    return {reward, t == 300 || reward >= 1};
  }
  std::vector<bool> Doors() const override { return {open_}; }

 private:
  bool open_ = false;
  std::vector<std::array<int, 2>> switches_;
};

// CMAE secret_rooms.py (S = 25): doors and walls reset every step, then the
// first active switch (main, 1, 2, 3; within 1.5) opens its doors.
class CmaeSecretRooms : public Reference {
 public:
  CmaeSecretRooms() : Reference(25) {
    const int third = S / 3, two = 2 * S / 3, half = S / 2;
    door_rows_ = {third / 2, (third + two) / 2, (two + S) / 2};
    switches_ = {{int(S * 0.8), int(S * 0.2)}, {door_rows_[0], int(S * 0.8)}, {door_rows_[1], int(S * 0.8)},
                 {door_rows_[2], int(S * 0.8)}};
    init_ = wall;
    for (int r = 0; r < S; ++r) init_[r][half] = 1;
    for (int c = half; c < S; ++c) init_[third][c] = init_[two][c] = 1;
    wall = init_;
    pos = {{3, 3}, {2, 2}};
    open_.assign(3, false);
  }
  std::pair<double, bool> Step(const std::vector<int>& actions) override {
    for (int i = 0; i < 2; ++i) Move(pos[i], actions[i]);
    wall = init_;
    open_.assign(3, false);
    bool done_update = false;
    for (int i = 0; i < 4 && !done_update; ++i) {
      for (const auto& p : pos) {
        if (Dist(p, switches_[i]) > 1.5) continue;
        for (int d = 0; d < 3; ++d) {
          if (i != 0 && d != i - 1) continue;
          open_[d] = true;
          for (int r = door_rows_[d] - 1; r <= door_rows_[d] + 1; ++r) wall[r][S / 2] = 0;
        }
        done_update = true;
        break;
      }
    }
    ++t;
    bool in = true;
    for (const auto& p : pos) in &= !(p[1] < S / 2.0 + 1 || p[0] > S / 3 + 1);
    const double reward = in ? 1 : 0;
    return {reward, t == 300 || reward >= 1};
  }
  std::vector<bool> Doors() const override { return open_; }

 private:
  std::vector<std::vector<int>> init_;
  std::vector<int> door_rows_;
  std::vector<std::array<int, 2>> switches_;
  std::vector<bool> open_;
};

// CMAE push_box.py (S = 15): forces from the positions before the move, the
// box moves if a direction has >= 2, then the agents move around it.
class CmaePushBox : public Reference {
 public:
  CmaePushBox() : Reference(15) {
    pos = {{11, 11}, {9, 9}};
    Walls();
  }
  std::pair<double, bool> Step(const std::vector<int>& actions) override {
    int force[4] = {0, 0, 0, 0};  // TOP, BOT, LEFT, RIGHT.
    const int top = box[0] - 1, bot = box[0] + 1, left = box[1] - 1, right = box[1] + 1;
    for (int i = 0; i < 2; ++i) {
      const int y = pos[i][0], x = pos[i][1];
      if (top <= y && y <= bot) {
        if (x == right + 1 && actions[i] == 2) ++force[2];
        else if (x == left - 1 && actions[i] == 3) ++force[3];
      }
      if (left <= x && x <= right) {
        if (y == top - 1 && actions[i] == 1) ++force[1];
        else if (y == bot + 1 && actions[i] == 0) ++force[0];
      }
    }
    for (int d = 0; d < 4; ++d) {
      if (force[d] < 2) continue;
      if (d == 0 && box[0] - 1 > 0) --box[0];
      if (d == 1 && box[0] + 1 < S - 1) ++box[0];
      if (d == 2 && box[1] - 1 > 0) --box[1];
      if (d == 3 && box[1] + 1 < S - 1) ++box[1];
      Walls();
    }
    for (int i = 0; i < 2; ++i) Move(pos[i], actions[i]);
    ++t;
    const bool edge = box[1] - 1 == 0 || box[1] + 1 == S - 1 || box[0] - 1 == 0 || box[0] + 1 == S - 1;
    const double reward = edge ? 1 : 0;
    return {reward, t == 300 || reward >= 1};
  }
  std::vector<bool> Doors() const override { return {}; }
  void Walls() {
    for (auto& row : wall) std::fill(row.begin(), row.end(), 0);
    for (int r = std::max(0, box[0] - 1); r < std::min(S, box[0] + 2); ++r) {
      for (int c = std::max(0, box[1] - 1); c < std::min(S, box[1] + 2); ++c) wall[r][c] = 1;
    }
  }

  std::array<int, 2> box{7, 7};
};

// MACE room.py map_ind 0 and secret_rooms.py map_ind 20 and 33 (S = 30,
// activate_radius 1.0): each door opens iff one of its switch sets is all on;
// walls reset from the initial map every step.
class MaceRooms : public Reference {
 public:
  struct Door {
    int row, col, horizontal;
    std::vector<std::vector<int>> sets;  // Switch index sets, any of which opens it.
    int radius;
  };
  // map_ind: 0 (Pass), 20 (SecretRoom), 33 (3-agent MultiRoom).
  explicit MaceRooms(int map_ind) : Reference(30), map_ind_(map_ind) {
    const int third = S / 3, two = S * 2 / 3;
    init_ = wall;
    for (int r = 0; r < S; ++r) init_[r][S / 2] = 1;
    if (map_ind == 0) {
      pos = {{4, 4}, {3, 3}};
      switches_ = {{3, 24}, {24, 3}};
      doors_ = {{S / 2, S / 2, 0, {{0}, {1}}, S / 10}};
    } else {
      for (int c = S / 2; c < S; ++c) init_[third][c] = init_[two][c] = 1;
      doors_ = {{third / 2, S / 2, 0, {{0}, {1}}, 1},
                {(third + two) / 2, S / 2, 0, {{0}, {2}}, 1},
                {(two + S) / 2, S / 2, 0, {{0}, {3}}, 1}};
      switches_ = {{int(S * 0.8), int(S * 0.2)}, {doors_[0].row, int(S * 0.8)}, {doors_[1].row, int(S * 0.8)},
                   {doors_[2].row, int(S * 0.8)}};
      pos = {{4, 4}, {3, 3}};
      if (map_ind == 33) {
        pos = {{3, 3}, {5, 3}, {3, 5}};
        doors_[0].sets = {{0}};
        doors_[1].sets = {{3}};
        doors_[2].sets = {{1}};
        doors_.push_back({third, S * 3 / 4, 1, {{2}}, 1});
        doors_.push_back({two, S * 3 / 4, 1, {{2}}, 1});
      }
    }
    wall = init_;
    open_.assign(doors_.size(), false);
  }
  std::pair<double, bool> Step(const std::vector<int>& actions) override {
    for (size_t i = 0; i < pos.size(); ++i) Move(pos[i], actions[i]);
    std::vector<bool> on(switches_.size(), false);
    for (size_t k = 0; k < switches_.size(); ++k) {
      for (const auto& p : pos) on[k] = on[k] || Dist(p, switches_[k]) <= 1.0;
    }
    wall = init_;
    for (size_t d = 0; d < doors_.size(); ++d) {
      const Door& door = doors_[d];
      open_[d] = false;
      for (const auto& set : door.sets) {
        bool all = true;
        for (int k : set) all &= on[k];
        if (all) open_[d] = true;
      }
      // Pass: the door cells are rewritten (closed) whether or not it opens.
      for (int k = -door.radius; k <= door.radius; ++k) {
        const int r = door.horizontal ? door.row : door.row + k, c = door.horizontal ? door.col + k : door.col;
        wall[r][c] = open_[d] ? 0 : 1;
      }
    }
    ++t;
    bool in = true;
    for (const auto& p : pos) {
      if (map_ind_ == 0) in &= p[1] > S / 2;
      if (map_ind_ == 20) in &= p[1] > S / 2 && p[0] < S / 3;
      if (map_ind_ == 33) in &= p[1] > S / 2 && p[0] > S / 3 && p[0] < S * 2 / 3;
    }
    return {in ? 100.0 : 0.0, in || t >= 300};
  }
  std::vector<bool> Doors() const override {
    if (map_ind_ != 33) return open_;
    // Ours: D is one door of six cells, the code's two doors that one switch opens.
    EXPECT_EQ(open_[3], open_[4]);
    return {open_[0], open_[1], open_[2], open_[3]};
  }
  const std::vector<std::array<int, 2>>& switches() const { return switches_; }
  const std::vector<Door>& doors() const { return doors_; }

 private:
  int map_ind_;
  std::vector<std::vector<int>> init_;
  std::vector<std::array<int, 2>> switches_;
  std::vector<Door> doors_;
  std::vector<bool> open_;
};

struct Variant {
  const char* scenario;
  int size;
  std::function<std::unique_ptr<Reference>()> make;
};

const std::vector<Variant>& Variants() {
  static const auto* variants = new std::vector<Variant>{
      {"pass_cmae", 30, [] { return std::unique_ptr<Reference>(new CmaeRooms()); }},
      {"secret_room_cmae", 25, [] { return std::unique_ptr<Reference>(new CmaeSecretRooms()); }},
      {"push_box_cmae", 15, [] { return std::unique_ptr<Reference>(new CmaePushBox()); }},
      {"pass_mace", 30, [] { return std::unique_ptr<Reference>(new MaceRooms(0)); }},
      {"secret_room_mace", 30, [] { return std::unique_ptr<Reference>(new MaceRooms(20)); }},
      {"multi_room3_mace", 30, [] { return std::unique_ptr<Reference>(new MaceRooms(33)); }},
  };
  return *variants;
}

std::unique_ptr<Scenario> MakeVariant(const std::string& name) {
  ScenarioConfig config;
  config.name = name;
  auto scenario = MakeScenario(config, DefaultMapDir());
  EXPECT_TRUE(scenario.ok()) << scenario.status();
  return *std::move(scenario);
}

// Our cell of the reference's (row, col): the maps add a border.
int Cell(const Scenario& s, const std::array<int, 2>& p) { return (p[0] + 1) * s.map().width() + p[1] + 1; }

// Whether our state blocks (row, col) as the reference's wall map does.
bool OursBlocks(const Scenario& s, const int32_t* state, int row, int col) {
  const int cell = (row + 1) * s.map().width() + col + 1;
  if (s.map().IsWall(cell)) return true;
  if (s.num_npcs() > 0 && s.Covers(state, 0, cell)) return true;
  const int door = s.map().DoorAt(cell);
  return door >= 0 && !s.DoorOpen(state, door);
}

TEST(VariantsTest, ResetsAreTheCodesStarts) {
  for (const Variant& v : Variants()) {
    SCOPED_TRACE(v.scenario);
    auto s = MakeVariant(v.scenario);
    auto ref = v.make();
    ASSERT_EQ(s->map().width(), v.size + 2);
    ASSERT_EQ(s->num_agents(), static_cast<int>(ref->pos.size()));
    EXPECT_EQ(s->num_actions(), 4);
    EXPECT_EQ(s->step_limit(), 300);
    EXPECT_TRUE(s->agents_share_cells());
    std::vector<int32_t> state(s->state_size());
    Rng rng(3);
    s->Reset(rng, state.data());
    for (size_t a = 0; a < ref->pos.size(); ++a) EXPECT_EQ(state[AgentIndex(a)], Cell(*s, ref->pos[a])) << a;
    for (int r = 0; r < v.size; ++r) {
      for (int c = 0; c < v.size; ++c) {
        EXPECT_EQ(OursBlocks(*s, state.data(), r, c), ref->wall[r][c] != 0) << "(" << r << ", " << c << ")";
      }
    }
    EXPECT_TRUE(s->ValidateState(state.data()).ok());
  }
}

// Starting spots where the rules act: around the switches, beside the doors
// (both sides) and beside the box, plus the code's own starts.
std::vector<std::array<int, 2>> Spots(const Scenario& s, const Reference& ref) {
  std::vector<std::array<int, 2>> spots = ref.pos;
  const GridMap& map = s.map();
  for (int cell = 0; cell < map.num_cells(); ++cell) {
    const bool rule = map.SwitchAt(cell) >= 0 || map.DoorAt(cell) >= 0 || !map.box_centres().empty();
    if (!rule) continue;
    for (int dr = -3; dr <= 3; ++dr) {
      for (int dc = -3; dc <= 3; ++dc) {
        const int r = map.Row(cell) - 1 + dr, c = map.Col(cell) - 1 + dc;
        if (r >= 0 && r < ref.S && c >= 0 && c < ref.S && !ref.wall[r][c]) spots.push_back({r, c});
      }
    }
    if (!map.box_centres().empty()) break;
  }
  return spots;
}

TEST(VariantsTest, StepByStepLikeTheReleasedCode) {
  for (const Variant& v : Variants()) {
    SCOPED_TRACE(v.scenario);
    auto s = MakeVariant(v.scenario);
    Rng rng(23);
    int64_t steps = 0, successes = 0, door_changes = 0, box_moves = 0;
    const int episodes = 400;
    for (int episode = 0; episode < episodes; ++episode) {
      auto ref = v.make();
      std::vector<int32_t> state(s->state_size(), 0);
      s->Reset(rng, state.data());
      const auto spots = Spots(*s, *ref);
      auto* push = dynamic_cast<CmaePushBox*>(ref.get());
      const int side = static_cast<int>(rng.Uniform(4));  // push_box: both agents start on this side.
      for (size_t a = 0; a < ref->pos.size(); ++a) {
        if (episode % 4 == 0) break;  // Every fourth episode from the code's starts.
        ref->pos[a] = spots[rng.Uniform(static_cast<uint32_t>(spots.size()))];
        if (push != nullptr) {
          // Beside the box, level with it, on the side opposite to a push `side`.
          const int along = static_cast<int>(rng.Uniform(3)) - 1;
          const int dr[4] = {2, -2, 0, 0}, dc[4] = {0, 0, 2, -2};  // Behind the box for up, down, left, right.
          ref->pos[a] = {push->box[0] + (dr[side] ? dr[side] : along), push->box[1] + (dc[side] ? dc[side] : along)};
        }
        state[AgentIndex(a)] = Cell(*s, ref->pos[a]);
      }
      ASSERT_TRUE(s->ValidateState(state.data()).ok()) << s->Render(state.data());
      std::vector<float> rewards(ref->pos.size());
      std::vector<int32_t> actions(ref->pos.size());
      std::vector<int> ref_actions(ref->pos.size());
      for (int t = 0; t < 300; ++t) {
        for (size_t a = 0; a < actions.size(); ++a) {
          ref_actions[a] = actions[a] = static_cast<int32_t>(rng.Uniform(4));
          // push_box: mostly push towards the box, so that it moves (and sometimes not).
          if (push != nullptr && episode % 4 != 0 && rng.Uniform(4) != 0) ref_actions[a] = actions[a] = side;
        }
        const int32_t before_z = state[kObjectsIndex];
        const int32_t before_box = s->num_npcs() ? state[1 + s->num_agents()] : 0;
        const auto [reward, done] = ref->Step(ref_actions);
        const StepOutcome outcome = s->Step(state.data(), actions.data(), rng, rewards.data());
        ++steps;
        SCOPED_TRACE(absl::StrCat("episode ", episode, " step ", t + 1, "\n", s->Render(state.data())));
        for (size_t a = 0; a < ref->pos.size(); ++a) ASSERT_EQ(state[AgentIndex(a)], Cell(*s, ref->pos[a])) << a;
        if (auto* box = dynamic_cast<CmaePushBox*>(ref.get())) {
          ASSERT_EQ(state[1 + s->num_agents()], Cell(*s, box->box));
          box_moves += state[1 + s->num_agents()] != before_box;
        }
        const std::vector<bool> doors = ref->Doors();
        for (size_t d = 0; d < doors.size(); ++d) ASSERT_EQ(s->DoorOpen(state.data(), d), doors[d]) << "door " << d;
        door_changes += state[kObjectsIndex] != before_z;
        for (int r = 0; r < v.size; ++r) {
          for (int c = 0; c < v.size; ++c) {
            ASSERT_EQ(OursBlocks(*s, state.data(), r, c), ref->wall[r][c] != 0) << "(" << r << ", " << c << ")";
          }
        }
        for (float x : rewards) ASSERT_EQ(x, static_cast<float>(reward));
        ASSERT_EQ(outcome.terminated || outcome.truncated, done);
        ASSERT_EQ(outcome.success, reward > 0);
        successes += outcome.success;
        if (done) break;
      }
    }
    // The rules were exercised, not only walked past.
    EXPECT_GT(successes, 0);
    if (std::string(v.scenario) == "push_box_cmae") {
      EXPECT_GT(box_moves, 10);
    } else {
      EXPECT_GT(door_changes, 100);
    }
    RecordProperty(v.scenario, absl::StrCat(steps, " steps, ", successes, " successes"));
  }
}

TEST(VariantsTest, SecretRoomCmaeAppliesOnlyTheFirstActiveSwitch) {
  // Agent 1 beside room switch 'a', agent 2 beside 'b': CMAE applies the
  // first active switch in the order '*', a, b, c and stops, so only door A
  // opens (MACE's rule would open A and B). With agent 1 gone, 'b' acts.
  auto s = MakeVariant("secret_room_cmae");
  const GridMap& map = s->map();
  std::vector<int32_t> state(s->state_size(), 0);
  int a = -1, b = -1;
  for (int cell = 0; cell < map.num_cells(); ++cell) {
    if (map.SwitchAt(cell) == 0) a = cell;
    if (map.SwitchAt(cell) == 1) b = cell;
  }
  state[AgentIndex(0)] = a - 1;
  state[AgentIndex(1)] = b - 1;
  Rng rng(1);
  float rewards[2];
  const int32_t onto[2] = {kRight, kRight};
  s->Step(state.data(), onto, rng, rewards);
  EXPECT_EQ(state[kObjectsIndex], 0b001) << s->Render(state.data());
  const int32_t away[2] = {kLeft, kUp};  // Agent 1: one cell off 'a' (still active); agent 2: beside 'b'.
  s->Step(state.data(), away, rng, rewards);
  EXPECT_EQ(state[kObjectsIndex], 0b001) << s->Render(state.data());
  const int32_t back[2] = {kLeft, kDown};  // Agent 1 two cells off 'a'; agent 2 on 'b': now 'b' acts.
  s->Step(state.data(), back, rng, rewards);
  EXPECT_EQ(state[kObjectsIndex], 0b010) << s->Render(state.data());
}

TEST(VariantsTest, TheCodesGoalRegions) {
  // secret_room_cmae's quirk: x >= 14 and y <= 9, so the top row of the
  // middle room counts and the top room's first column does not.
  auto s = MakeVariant("secret_room_cmae");
  const GridMap& map = s->map();
  std::vector<int32_t> state(s->state_size(), 0);
  Rng rng(1);
  float rewards[2];
  const int32_t stay[2] = {kRight, kRight};
  auto at = [&](int y, int x) { return (y + 1) * map.width() + x + 1; };
  // Both in the middle room's top row (y = 9), x = 20 and 21, moving right.
  state[AgentIndex(0)] = at(9, 20);
  state[AgentIndex(1)] = at(9, 21);
  EXPECT_TRUE(s->Step(state.data(), stay, rng, rewards).success);
  EXPECT_EQ(rewards[0], 1.0f);
  // The top room's first column (x = 13): moving up keeps x, not a success.
  state[AgentIndex(0)] = at(5, 13);
  state[AgentIndex(1)] = at(6, 13);
  state[s->step_index()] = 0;
  const int32_t up[2] = {kUp, kUp};
  EXPECT_FALSE(s->Step(state.data(), up, rng, rewards).success);
}

}  // namespace
}  // namespace imca::env
