#ifndef IMCA_COMMON_GRID_MAP_H_
#define IMCA_COMMON_GRID_MAP_H_

#include <cstdint>
#include <string>
#include "absl/strings/string_view.h"
#include <vector>

#include "absl/status/statusor.h"

namespace imca::env {

// A gridworld layout read from an ASCII map file. Legend (one character per
// cell; every row the same width; see docs/maps.md):
//   '#' wall            '.' floor
//   '1'..'9' fixed spawn cell of agent 1..9 (floor)
//   'S' random-spawn cell (floor): agents without a fixed spawn start on
//       distinct cells drawn uniformly from these at every reset
//   'T' treasure (floor)
// Lines whose first character is ';' are comments; blank lines are ignored.
// Cells are numbered row-major: cell = row * width + col.
// Immutable after Parse; safe to share between threads.
class GridMap {
 public:
  enum Cell : uint8_t { kFloor = 0, kWall = 1 };

  // Parses `text`. Errors: INVALID_ARGUMENT naming `source`, line and column
  // of the first bad character, or the problem (ragged rows, no rows, too big).
  static absl::StatusOr<GridMap> Parse(absl::string_view text, absl::string_view source);
  // Reads and parses the file at `path`. Errors: NOT_FOUND if it cannot be
  // read, plus those of Parse.
  static absl::StatusOr<GridMap> Load(const std::string& path);

  int width() const { return width_; }
  int height() const { return height_; }
  int num_cells() const { return width_ * height_; }
  bool IsWall(int cell) const { return cells_[cell] == kWall; }
  int Row(int cell) const { return cell / width_; }
  int Col(int cell) const { return cell % width_; }
  // Fixed spawn of agent a (0-based) or -1 when it spawns at random.
  int FixedSpawn(int agent) const {
    return agent < static_cast<int>(fixed_spawns_.size()) ? fixed_spawns_[agent] : -1;
  }
  int num_fixed_spawns() const;
  const std::vector<int32_t>& random_spawns() const { return random_spawns_; }
  const std::vector<int32_t>& treasures() const { return treasures_; }
  const std::string& source() const { return source_; }

 private:
  int width_ = 0;
  int height_ = 0;
  std::vector<uint8_t> cells_;
  std::vector<int32_t> fixed_spawns_;  // Index = agent, -1 = none.
  std::vector<int32_t> random_spawns_;
  std::vector<int32_t> treasures_;
  std::string source_;
};

}  // namespace imca::env

#endif  // IMCA_COMMON_GRID_MAP_H_
