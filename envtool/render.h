#ifndef IMCA_ENVTOOL_RENDER_H_
#define IMCA_ENVTOOL_RENDER_H_

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/env/env.h"

struct GifFileType;  // gif_lib.h

namespace imca::envtool {

// The fixed palette every picture is drawn in (docs/envtool.md shows it).
// Pictures hold palette indexes, so a GIF frame needs no quantisation.
enum Color : uint8_t {
  kFloor,
  kGridLine,
  kWall,
  kDoorClosed,  // Fill of a closed door; its border is in the door's colour.
  kDoorOpen,    // Fill of an open door.
  kTreasure,
  kButton,                                     // Ring of a released button.
  kButtonPressed,                              // Disk of a pressed button (around the agent on it).
  kPreyZone,                                   // Floor tint.
  kGoalRoom,                                   // Floor tint.
  kNpc,                                        // The prey.
  kFirstAgent,                                 // Agent a: kFirstAgent + a.
  kFirstDoor = kFirstAgent + env::kMaxAgents,  // Door d and its switches: kFirstDoor + d,
                                               // then a switch of every door ('*').
  kNumColors = kFirstDoor + env::GridMap::kEveryDoor + 1,
};
inline uint8_t AgentColor(int agent) { return static_cast<uint8_t>(kFirstAgent + agent); }
inline uint8_t DoorColor(int door) { return static_cast<uint8_t>(kFirstDoor + door); }

struct Rgb {
  uint8_t r, g, b;
  bool operator==(const Rgb& o) const { return r == o.r && g == o.g && b == o.b; }
  bool operator!=(const Rgb& o) const { return !(*this == o); }
};
// RGB of palette index `color` (< kNumColors).
Rgb PaletteRgb(uint8_t color);

// A picture in palette indexes, row-major, one byte per pixel.
struct Image {
  int width = 0;
  int height = 0;
  std::vector<uint8_t> pixels;
};

// Draws states of one scenario, cell_px x cell_px pixels per cell: walls dark
// grey; floor white with a thin grid, tinted green in the prey zone and blue
// in the goal room (GridMap::GoalRoom, on maps with doors); doors brown when
// closed, tan when open, both bordered in the door's colour; switches small
// squares in their door's colour; treasures gold diamonds until collected;
// buttons rings, filled while pressed; agents disks in their own colours; the
// prey a red triangle.
// Immutable after Create; thread-safe. The scenario must outlive it.
class Renderer {
 public:
  static constexpr int kMinCellPx = 4;
  static constexpr int kMaxCellPx = 64;

  // Errors: INVALID_ARGUMENT if cell_px is outside [kMinCellPx, kMaxCellPx].
  static absl::StatusOr<Renderer> Create(const env::Scenario* scenario, int cell_px = 24);

  int cell_px() const { return cell_px_; }
  int width() const { return background_.width; }
  int height() const { return background_.height; }

  // Draws `state` (scenario().state_size() values that pass ValidateState).
  Image Draw(const int32_t* state) const;

 private:
  Renderer(const env::Scenario* scenario, int cell_px);

  const env::Scenario* scenario_;
  int cell_px_;
  Image background_;  // What no state changes: walls, floor tints, grid.
};

// Writes `image` as an 8-bit palette PNG (libpng). Errors: INVALID_ARGUMENT
// for an empty image; INTERNAL naming `path` if it cannot be written.
absl::Status WritePng(const Image& image, const std::string& path);

// Writes an animated GIF frame by frame with giflib, looping forever; frames
// are palette indexes already, so nothing is quantised, and each frame stores
// only the rectangle that changed. Memory does not grow with the number of
// frames. Not thread-safe.
class GifWriter {
 public:
  // Creates `path` for width x height frames, each shown delay_cs hundredths
  // of a second. Errors: INVALID_ARGUMENT for an empty size or a delay outside
  // [1, 65535]; INTERNAL naming `path` if it cannot be created.
  static absl::StatusOr<std::unique_ptr<GifWriter>> Create(const std::string& path, int width, int height,
                                                           int delay_cs);
  GifWriter(const GifWriter&) = delete;
  GifWriter& operator=(const GifWriter&) = delete;
  ~GifWriter();  // Closes the file if Close was not called, dropping errors.

  // Appends `frame`. Errors: INVALID_ARGUMENT if its size differs from the
  // writer's; INTERNAL naming the path if writing fails (later calls fail too).
  absl::Status AddFrame(const Image& frame);
  // Finishes the file. Returns the first error of the writer. Call once.
  absl::Status Close();
  int num_frames() const { return num_frames_; }

 private:
  GifWriter(std::string path, GifFileType* gif, int width, int height, int delay_cs);
  absl::Status Error(int code) const;

  std::string path_;
  GifFileType* gif_;  // Owned; null once closed.
  int width_;
  int height_;
  int delay_cs_;
  int num_frames_ = 0;
  std::vector<uint8_t> previous_;  // Pixels of the last frame.
  absl::Status status_;            // Sticky: the first error.
};

// Writes `frames` (all one size, at least one) through a GifWriter. Errors:
// those of GifWriter, and INVALID_ARGUMENT naming `path` for no frames.
absl::Status WriteGif(const std::vector<Image>& frames, const std::string& path, int delay_cs);

}  // namespace imca::envtool

#endif  // IMCA_ENVTOOL_RENDER_H_
