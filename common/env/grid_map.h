#ifndef IMCA_COMMON_ENV_GRID_MAP_H_
#define IMCA_COMMON_ENV_GRID_MAP_H_

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace imca::env {

// A gridworld layout read from an ASCII map file. One legend for every
// scenario (docs/scenarios.md); one character per cell, every row the same width:
//   '#' wall              '.' floor
//   '1'..'9' fixed spawn of agent 1..9      'S' random agent spawn
//   'T' treasure          'X' button        'Z' prey zone (prey spawns and moves only here)
//   'O' the centre of a 3x3 box agents push (push_box_cmae; its 8 other cells are floor in the file)
//   'G' goal marker: the room (door-free connected region) holding it is the goal room
//   'A'..'F' a cell of door 0..5 (several cells with one letter form one wide door)
//   'a'..'f' a switch of door 0..5      '*' a switch of every door (EDTI's main switch)
//   '@' fixed spawn of every agent (scenarios whose agents may share a cell)
// Every special cell is also floor. Lines whose first character is ';' are
// comments; blank lines are ignored. Cells are numbered row-major:
// cell = row * width + col. Immutable after Parse; safe to share.
class GridMap {
 public:
  static constexpr int kMaxDoors = 6;
  static constexpr int kMaxSide = 256;

  // Parses `text`. Errors: INVALID_ARGUMENT naming `source`, line and column
  // of the first bad character, or the problem (ragged rows, no rows, too big,
  // a switch without its door).
  static absl::StatusOr<GridMap> Parse(absl::string_view text, absl::string_view source);
  // Reads and parses the file at `path`. Errors: NOT_FOUND if it cannot be
  // read, plus those of Parse.
  static absl::StatusOr<GridMap> Load(const std::string& path);

  int width() const { return width_; }
  int height() const { return height_; }
  int num_cells() const { return width_ * height_; }
  bool IsWall(int cell) const { return wall_[cell] != 0; }
  int Row(int cell) const { return cell / width_; }
  int Col(int cell) const { return cell % width_; }

  // Fixed spawn of agent a (0-based) or -1 when it spawns at random.
  int FixedSpawn(int agent) const {
    if (shared_spawn_ >= 0) return shared_spawn_;
    return agent < static_cast<int>(fixed_spawns_.size()) ? fixed_spawns_[agent] : -1;
  }
  // The '@' cell, or -1.
  int shared_spawn() const { return shared_spawn_; }
  const std::vector<int32_t>& random_spawns() const { return random_spawns_; }
  const std::vector<int32_t>& treasures() const { return treasures_; }
  const std::vector<int32_t>& buttons() const { return buttons_; }
  const std::vector<int32_t>& box_centres() const { return box_centres_; }
  const std::vector<int32_t>& prey_zone() const { return prey_zone_; }
  const std::vector<int32_t>& goal_markers() const { return goal_markers_; }
  bool InPreyZone(int cell) const { return zone_[cell] != 0; }

  // Doors 0..num_doors()-1 (letters 'A'..), each a set of cells and switches.
  int num_doors() const { return static_cast<int>(door_cells_.size()); }
  // Door whose cell this is, or -1.
  int DoorAt(int cell) const { return door_of_[cell]; }
  // Door this switch opens, kEveryDoor for a '*' switch, or -1.
  static constexpr int kEveryDoor = kMaxDoors;
  int SwitchAt(int cell) const { return switch_of_[cell]; }
  const std::vector<int32_t>& door_cells(int door) const { return door_cells_[door]; }
  // The switches that open `door`: its own and every '*'.
  const std::vector<int32_t>& switches(int door) const { return switches_[door]; }

  // Cells of the room holding the 'G' markers or, if there are none, the
  // treasures: the region reachable from them without crossing walls or
  // doors. Empty if the map has neither.
  std::vector<bool> GoalRoom() const;
  // The region reachable from `seeds` without crossing walls or door cells
  // (the seeds included), as a cell mask.
  std::vector<bool> RoomOf(const std::vector<int32_t>& seeds) const;

  const std::string& source() const { return source_; }

 private:
  int width_ = 0;
  int height_ = 0;
  std::vector<uint8_t> wall_;
  std::vector<uint8_t> zone_;
  std::vector<int8_t> door_of_;
  std::vector<int8_t> switch_of_;
  std::vector<int32_t> fixed_spawns_;  // Index = agent, -1 = none.
  int32_t shared_spawn_ = -1;
  std::vector<int32_t> random_spawns_;
  std::vector<int32_t> treasures_;
  std::vector<int32_t> buttons_;
  std::vector<int32_t> box_centres_;
  std::vector<int32_t> prey_zone_;
  std::vector<int32_t> goal_markers_;
  std::vector<std::vector<int32_t>> door_cells_;
  std::vector<std::vector<int32_t>> switches_;
  std::string source_;
};

}  // namespace imca::env

#endif  // IMCA_COMMON_ENV_GRID_MAP_H_
