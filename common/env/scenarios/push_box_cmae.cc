#include <cstdint>
#include <cstdlib>
#include <string>
#include <utility>

#include "common/env/scenarios/registry.h"

namespace imca::env {
namespace {

// CMAE's push_box (CMAE's env/push_box.py): a 3x3 box (entity 0,
// its centre cell; its nine cells block the agents) that moves one cell in a
// direction when at least two agents, each beside the box on the opposite
// side and level with it, push that way in the same step, unless a wall lies
// beyond. The box moves first, then the agents (on the box's new cells).
// Success: a side of the box lies against a wall (the grid's edge in CMAE's
// border-free grid). 4 actions, agents may share a cell.
class PushBox final : public Scenario {
 public:
  PushBox(GridMap map, const ScenarioConfig& config, int n)
      : Scenario(std::move(map), config, n, 1, 4, 300, 1.0f, 0.0f, /*agents_share_cells=*/true) {}

  absl::string_view name() const override { return "push_box_cmae"; }
  int num_object_bits() const override { return 0; }
  bool Covers(const int32_t* state, int entity, int cell) const override {
    const int box = state[1 + num_agents_ + entity];
    return std::abs(map_.Row(cell) - map_.Row(box)) <= 1 && std::abs(map_.Col(cell) - map_.Col(box)) <= 1;
  }
  char EntityChar() const override { return 'O'; }

  void Reset(Rng& rng, int32_t* state) const override {
    Scenario::Reset(rng, state);
    state[1 + num_agents_] = map_.box_centres()[0];
  }

  StepOutcome Step(int32_t* state, const int32_t* actions, Rng& rng, float* rewards) const override {
    int32_t& box = state[1 + num_agents_];
    const int top = map_.Row(box) - 1, bot = map_.Row(box) + 1, left = map_.Col(box) - 1, right = map_.Col(box) + 1;
    int force[4] = {0, 0, 0, 0};  // By our action code: up, down, left, right.
    for (int a = 0; a < num_agents_; ++a) {
      const int row = map_.Row(state[AgentIndex(a)]), col = map_.Col(state[AgentIndex(a)]);
      if (row >= top && row <= bot) {
        if (col == right + 1 && actions[a] == kLeft) ++force[kLeft];
        else if (col == left - 1 && actions[a] == kRight) ++force[kRight];
      }
      if (col >= left && col <= right) {
        if (row == top - 1 && actions[a] == kDown) ++force[kDown];
        else if (row == bot + 1 && actions[a] == kUp) ++force[kUp];
      }
    }
    for (int u = 0; u < 4; ++u) {
      if (force[u] < 2) continue;
      if (!Blocked(box, u)) box += kActionRow[u] * map_.width() + kActionCol[u];
      break;
    }
    // Agents move onto floor that is not the box: MoveAgents' `others` holds
    // single cells, so the box is checked here.
    for (int a = 0; a < num_agents_; ++a) {
      int32_t& cell = state[AgentIndex(a)];
      const int row = map_.Row(cell) + kActionRow[actions[a]], col = map_.Col(cell) + kActionCol[actions[a]];
      if (row < 0 || row >= map_.height() || col < 0 || col >= map_.width()) continue;
      const int target = row * map_.width() + col;
      if (!map_.IsWall(target) && !Covers(state, 0, target)) cell = target;
    }
    const int t = ++state[step_index()];
    bool against = false;
    for (int u = 0; u < 4; ++u) against |= Blocked(box, u);
    return Finish(t, against, rewards);
  }

 private:
  // True if a wall (or the grid's edge) lies beyond the box's side in direction u.
  bool Blocked(int box, int u) const {
    for (int k = -1; k <= 1; ++k) {
      const int row = map_.Row(box) + 2 * kActionRow[u] + (kActionRow[u] == 0 ? k : 0);
      const int col = map_.Col(box) + 2 * kActionCol[u] + (kActionCol[u] == 0 ? k : 0);
      if (row < 0 || row >= map_.height() || col < 0 || col >= map_.width() ||
          map_.IsWall(row * map_.width() + col)) {
        return true;
      }
    }
    return false;
  }
};

std::string NeedBox(const GridMap& m) {
  if (m.box_centres().size() != 1) return "needs exactly one box centre 'O'";
  const int box = m.box_centres()[0];
  for (int dr = -1; dr <= 1; ++dr) {
    for (int dc = -1; dc <= 1; ++dc) {
      const int row = m.Row(box) + dr, col = m.Col(box) + dc;
      if (row < 0 || row >= m.height() || col < 0 || col >= m.width() || m.IsWall(row * m.width() + col)) {
        return "needs the 3x3 box around 'O' on floor";
      }
    }
  }
  return "";
}

}  // namespace

// The bonus at the task's scale, as the other CMAE tasks (switch_rooms.cc).
absl::Status RegisterPushBoxCmae(ScenarioRegistry* registry) {
  return registry->Add(MakeScenarioEntry<PushBox>("push_box_cmae", 2, NeedBox,
                                                  {/*batch_steps=*/{}, /*learning_rate=*/{},
                                                   /*separate_optimizers=*/{}, /*unroll_length=*/{},
                                                   /*bonus_scale=*/1e-3}));
}

}  // namespace imca::env
