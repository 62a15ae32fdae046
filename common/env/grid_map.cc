#include "common/env/grid_map.h"

#include <algorithm>

#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "common/base/atomic_file.h"

namespace imca::env {

absl::StatusOr<GridMap> GridMap::Parse(absl::string_view text, absl::string_view source) {
  GridMap map;
  map.source_ = std::string(source);
  int line_no = 0;
  int row = 0;
  int max_door = -1;
  std::vector<std::pair<int, int>> switch_lines(kMaxDoors, {0, 0});  // Where a switch was seen.
  std::pair<int, int> master_line{0, 0};                             // Where a '*' was seen.
  for (absl::string_view line : absl::StrSplit(text, '\n')) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (line.empty() || line[0] == ';') continue;
    const int width = static_cast<int>(line.size());
    if (map.width_ == 0) {
      if (width > kMaxSide) {
        return absl::InvalidArgumentError(
            absl::StrCat(source, ":", line_no, ":", kMaxSide + 1, ": row is wider than ", kMaxSide, " cells"));
      }
      map.width_ = width;
    } else if (width != map.width_) {
      return absl::InvalidArgumentError(absl::StrCat(source, ":", line_no, ":", std::min(width, map.width_) + 1,
                                                     ": row has ", width, " cells, expected ", map.width_));
    }
    if (row >= kMaxSide) {
      return absl::InvalidArgumentError(absl::StrCat(source, ":", line_no, ":1: more than ", kMaxSide, " rows"));
    }
    for (int col = 0; col < width; ++col) {
      const int cell = row * width + col;
      const char c = line[col];
      uint8_t wall = 0, zone = 0;
      int8_t door = -1, sw = -1;
      if (c == '#') {
        wall = 1;
      } else if (c == '.') {
      } else if (c >= '1' && c <= '9') {
        const int agent = c - '1';
        if (static_cast<int>(map.fixed_spawns_.size()) <= agent) map.fixed_spawns_.resize(agent + 1, -1);
        if (map.fixed_spawns_[agent] != -1) {
          return absl::InvalidArgumentError(
              absl::StrCat(source, ":", line_no, ":", col + 1, ": second spawn for agent ", agent + 1));
        }
        map.fixed_spawns_[agent] = cell;
      } else if (c == '@') {
        if (map.shared_spawn_ != -1) {
          return absl::InvalidArgumentError(
              absl::StrCat(source, ":", line_no, ":", col + 1, ": second '@' (spawn of every agent)"));
        }
        map.shared_spawn_ = cell;
      } else if (c == '*') {
        sw = kEveryDoor;
        if (master_line.first == 0) master_line = {line_no, col + 1};
      } else if (c == 'S') {
        map.random_spawns_.push_back(cell);
      } else if (c == 'T') {
        map.treasures_.push_back(cell);
      } else if (c == 'X') {
        map.buttons_.push_back(cell);
      } else if (c == 'O') {
        map.box_centres_.push_back(cell);
      } else if (c == 'Z') {
        zone = 1;
        map.prey_zone_.push_back(cell);
      } else if (c == 'G') {
        map.goal_markers_.push_back(cell);
      } else if (c >= 'A' && c < 'A' + kMaxDoors) {
        door = static_cast<int8_t>(c - 'A');
      } else if (c >= 'a' && c < 'a' + kMaxDoors) {
        sw = static_cast<int8_t>(c - 'a');
        if (switch_lines[sw].first == 0) switch_lines[sw] = {line_no, col + 1};
      } else {
        return absl::InvalidArgumentError(
            absl::StrCat(source, ":", line_no, ":", col + 1, ": unknown map character '", absl::CHexEscape(std::string(1, c)),
                         "' (legend: # . 1-9 @ S T X O Z G A-F a-f *)"));
      }
      max_door = std::max<int>(max_door, std::max<int>(door, sw == kEveryDoor ? -1 : sw));
      map.wall_.push_back(wall);
      map.zone_.push_back(zone);
      map.door_of_.push_back(door);
      map.switch_of_.push_back(sw);
    }
    ++row;
  }
  map.height_ = row;
  if (map.height_ == 0) return absl::InvalidArgumentError(absl::StrCat(source, ": map has no rows"));
  if (map.shared_spawn_ >= 0 && !map.fixed_spawns_.empty()) {
    return absl::InvalidArgumentError(
        absl::StrCat(source, ": '@' (spawn of every agent) and spawns '1'-'9' cannot be mixed"));
  }
  if (master_line.first != 0 && max_door < 0) {
    return absl::InvalidArgumentError(absl::StrCat(source, ":", master_line.first, ":", master_line.second,
                                                   ": switch '*' but no door 'A'-'F'"));
  }
  if (map.treasures_.size() > 16) {
    return absl::InvalidArgumentError(absl::StrCat(source, ": at most 16 treasures are supported"));
  }
  if (map.buttons_.size() > 16) {
    return absl::InvalidArgumentError(absl::StrCat(source, ": at most 16 buttons are supported"));
  }
  map.door_cells_.resize(max_door + 1);
  map.switches_.resize(max_door + 1);
  for (int cell = 0; cell < map.num_cells(); ++cell) {
    if (map.door_of_[cell] >= 0) map.door_cells_[map.door_of_[cell]].push_back(cell);
    const int sw = map.switch_of_[cell];
    if (sw == kEveryDoor) {
      for (auto& switches : map.switches_) switches.push_back(cell);
    } else if (sw >= 0) {
      map.switches_[sw].push_back(cell);
    }
  }
  for (int d = 0; d <= max_door; ++d) {
    if (map.door_cells_[d].empty()) {
      const auto [line, col] = switch_lines[d];
      return absl::InvalidArgumentError(absl::StrCat(source, ":", line, ":", col, ": switch '",
                                                     std::string(1, 'a' + d), "' has no door '",
                                                     std::string(1, 'A' + d), "'"));
    }
  }
  return map;
}

absl::StatusOr<GridMap> GridMap::Load(const std::string& path) {
  absl::StatusOr<std::string> text = ReadFile(path, "map file");
  if (!text.ok()) return text.status();
  return Parse(*text, path);
}

std::vector<bool> GridMap::GoalRoom() const { return RoomOf(goal_markers_.empty() ? treasures_ : goal_markers_); }

std::vector<bool> GridMap::RoomOf(const std::vector<int32_t>& seeds) const {
  std::vector<bool> room(num_cells(), false);
  std::vector<int32_t> frontier = seeds;
  for (int32_t cell : frontier) room[cell] = true;
  while (!frontier.empty()) {
    const int cell = frontier.back();
    frontier.pop_back();
    const int r = Row(cell), c = Col(cell);
    const int neighbours[4][2] = {{r - 1, c}, {r + 1, c}, {r, c - 1}, {r, c + 1}};
    for (const auto& [nr, nc] : neighbours) {
      if (nr < 0 || nr >= height_ || nc < 0 || nc >= width_) continue;
      const int next = nr * width_ + nc;
      if (room[next] || IsWall(next) || DoorAt(next) >= 0) continue;
      room[next] = true;
      frontier.push_back(next);
    }
  }
  return room;
}

}  // namespace imca::env
