#include "common/grid_map.h"

#include <fstream>
#include <sstream>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"

namespace imca::env {

absl::StatusOr<GridMap> GridMap::Parse(absl::string_view text, absl::string_view source) {
  constexpr int kMaxSide = 256;
  GridMap map;
  map.source_ = std::string(source);
  int line_no = 0;
  int row = 0;
  for (absl::string_view line : absl::StrSplit(text, '\n')) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (line.empty() || line[0] == ';') continue;
    if (map.width_ == 0) {
      map.width_ = static_cast<int>(line.size());
      if (map.width_ > kMaxSide) {
        return absl::InvalidArgumentError(absl::StrCat(source, ":", line_no, ": row is wider than ",
                                                       kMaxSide, " cells"));
      }
    } else if (static_cast<int>(line.size()) != map.width_) {
      return absl::InvalidArgumentError(
          absl::StrCat(source, ":", line_no, ":", std::min<int>(line.size(), map.width_) + 1,
                       ": row has ", line.size(), " cells, expected ", map.width_));
    }
    if (row >= kMaxSide) {
      return absl::InvalidArgumentError(
          absl::StrCat(source, ":", line_no, ": more than ", kMaxSide, " rows"));
    }
    for (int col = 0; col < map.width_; ++col) {
      const int cell = row * map.width_ + col;
      const char c = line[col];
      uint8_t type = kFloor;
      if (c == '#') {
        type = kWall;
      } else if (c == '.') {
      } else if (c >= '1' && c <= '9') {
        const int agent = c - '1';
        if (static_cast<int>(map.fixed_spawns_.size()) <= agent) map.fixed_spawns_.resize(agent + 1, -1);
        if (map.fixed_spawns_[agent] != -1) {
          return absl::InvalidArgumentError(absl::StrCat(source, ":", line_no, ":", col + 1,
                                                         ": second spawn for agent ", agent + 1));
        }
        map.fixed_spawns_[agent] = cell;
      } else if (c == 'S') {
        map.random_spawns_.push_back(cell);
      } else if (c == 'T') {
        map.treasures_.push_back(cell);
      } else {
        return absl::InvalidArgumentError(absl::StrCat(source, ":", line_no, ":", col + 1,
                                                       ": unknown map character '", std::string(1, c),
                                                       "' (legend: # . 1-9 S T)"));
      }
      map.cells_.push_back(type);
    }
    ++row;
  }
  map.height_ = row;
  if (map.height_ == 0) return absl::InvalidArgumentError(absl::StrCat(source, ": map has no rows"));
  if (map.treasures_.size() > 16) {
    return absl::InvalidArgumentError(absl::StrCat(source, ": at most 16 treasures are supported"));
  }
  return map;
}

absl::StatusOr<GridMap> GridMap::Load(const std::string& path) {
  std::ifstream in(path);
  if (!in) return absl::NotFoundError(absl::StrCat("cannot read map file '", path, "'"));
  std::stringstream buffer;
  buffer << in.rdbuf();
  return Parse(buffer.str(), path);
}

int GridMap::num_fixed_spawns() const {
  int count = 0;
  for (int32_t cell : fixed_spawns_) count += cell >= 0;
  return count;
}

}  // namespace imca::env
