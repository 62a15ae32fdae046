#include "envtool/render.h"

#include <fcntl.h>
#include <gif_lib.h>
#include <png.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstring>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"

namespace imca::envtool {
namespace {

constexpr std::array<Rgb, kNumColors> kPalette = {{
    {255, 255, 255},  // kFloor
    {214, 214, 214},  // kGridLine
    {64, 64, 64},     // kWall
    {128, 78, 32},    // kDoorClosed
    {236, 214, 170},  // kDoorOpen
    {245, 190, 0},    // kTreasure
    {170, 30, 30},    // kButton
    {120, 220, 60},   // kButtonPressed
    {214, 242, 206},  // kPreyZone
    {208, 226, 250},  // kGoalRoom
    {225, 20, 20},    // kNpc
    // Agents 1..9.
    {31, 119, 180},
    {255, 127, 14},
    {44, 160, 44},
    {148, 103, 189},
    {227, 119, 194},
    {23, 190, 207},
    {188, 189, 34},
    {20, 40, 120},
    {0, 128, 128},
    // Doors 'A'..'F' and their switches.
    {230, 25, 75},
    {0, 90, 200},
    {0, 150, 60},
    {145, 30, 180},
    {240, 120, 0},
    {0, 200, 200},
    {0, 0, 0},  // A switch of every door.
}};
static_assert(sizeof(Rgb) == 3, "libpng reads the palette as packed RGB triples");

// Drawing on an Image in cell-relative geometry: shapes are centred on the
// cell's centre and sized in fractions of the cell.
class Canvas {
 public:
  Canvas(Image* image, int cell_px) : image_(image), px_(cell_px) {}

  void FillCell(int row, int col, uint8_t color) { Inset(row, col, 0, color); }

  // Fills the cell shrunk by `inset` pixels on every side.
  void Inset(int row, int col, int inset, uint8_t color) {
    const int x0 = col * px_ + inset, y0 = row * px_ + inset;
    for (int y = y0; y < y0 + px_ - 2 * inset; ++y) {
      std::fill_n(&image_->pixels[static_cast<size_t>(y) * image_->width + x0], px_ - 2 * inset, color);
    }
  }

  // Fills each pixel of the cell whose centre (dx, dy), measured from the
  // cell's centre in cell units, satisfies `inside`.
  template <typename Inside>
  void Shape(int row, int col, uint8_t color, Inside inside) {
    for (int y = 0; y < px_; ++y) {
      for (int x = 0; x < px_; ++x) {
        const double dx = (x + 0.5) / px_ - 0.5, dy = (y + 0.5) / px_ - 0.5;
        if (inside(dx, dy)) {
          image_->pixels[static_cast<size_t>(row * px_ + y) * image_->width + col * px_ + x] = color;
        }
      }
    }
  }

  void Disk(int row, int col, double radius, uint8_t color) {
    Shape(row, col, color, [=](double dx, double dy) { return dx * dx + dy * dy <= radius * radius; });
  }
  void Ring(int row, int col, double outer, double inner, uint8_t color) {
    Shape(row, col, color, [=](double dx, double dy) {
      const double d2 = dx * dx + dy * dy;
      return d2 <= outer * outer && d2 >= inner * inner;
    });
  }
  void Square(int row, int col, double half, uint8_t color) {
    Shape(row, col, color,
          [=](double dx, double dy) { return std::abs(dx) <= half && std::abs(dy) <= half; });
  }
  void Diamond(int row, int col, double radius, uint8_t color) {
    Shape(row, col, color, [=](double dx, double dy) { return std::abs(dx) + std::abs(dy) <= radius; });
  }
  // Pointing up: apex at dy = -0.38, base at dy = +0.32, 0.76 wide.
  void Triangle(int row, int col, uint8_t color) {
    Shape(row, col, color, [](double dx, double dy) {
      return dy >= -0.38 && dy <= 0.32 && std::abs(dx) <= 0.38 * (dy + 0.38) / 0.70;
    });
  }

 private:
  Image* image_;
  int px_;
};

}  // namespace

Rgb PaletteRgb(uint8_t color) { return kPalette[color]; }

absl::StatusOr<Renderer> Renderer::Create(const env::Scenario* scenario, int cell_px) {
  if (cell_px < kMinCellPx || cell_px > kMaxCellPx) {
    return absl::InvalidArgumentError(
        absl::StrCat("cell size ", cell_px, " px not in [", kMinCellPx, ", ", kMaxCellPx, "]"));
  }
  return Renderer(scenario, cell_px);
}

Renderer::Renderer(const env::Scenario* scenario, int cell_px) : scenario_(scenario), cell_px_(cell_px) {
  const env::GridMap& map = scenario->map();
  background_.width = map.width() * cell_px;
  background_.height = map.height() * cell_px;
  background_.pixels.assign(static_cast<size_t>(background_.width) * background_.height, kGridLine);
  Canvas canvas(&background_, cell_px);
  // Without doors the goal room would be all the floor: tint it only with doors.
  const std::vector<bool> goal_room = map.num_doors() > 0 ? map.GoalRoom() : std::vector<bool>();
  for (int cell = 0; cell < map.num_cells(); ++cell) {
    const int row = map.Row(cell), col = map.Col(cell);
    if (map.IsWall(cell)) {
      canvas.FillCell(row, col, kWall);
      continue;
    }
    uint8_t floor = kFloor;
    if (map.InPreyZone(cell)) {
      floor = kPreyZone;
    } else if (!goal_room.empty() && goal_room[cell]) {
      floor = kGoalRoom;
    }
    // The grid: a one-pixel line on the top and left edges of each floor cell.
    for (int y = row * cell_px + 1; y < (row + 1) * cell_px; ++y) {
      std::fill_n(&background_.pixels[static_cast<size_t>(y) * background_.width + col * cell_px + 1],
                  cell_px - 1, floor);
    }
    if (map.SwitchAt(cell) >= 0) canvas.Square(row, col, 0.28, DoorColor(map.SwitchAt(cell)));
  }
}

Image Renderer::Draw(const int32_t* state) const {
  const env::Scenario& s = *scenario_;
  const env::GridMap& map = s.map();
  Image image = background_;
  Canvas canvas(&image, cell_px_);
  const int border = std::max(1, cell_px_ / 10);
  for (int d = 0; d < map.num_doors(); ++d) {
    const bool open = s.DoorOpen(state, d);
    for (int32_t cell : map.door_cells(d)) {
      canvas.FillCell(map.Row(cell), map.Col(cell), DoorColor(d));
      canvas.Inset(map.Row(cell), map.Col(cell), border, open ? kDoorOpen : kDoorClosed);
    }
  }
  const auto& treasures = map.treasures();
  for (size_t k = 0; k < treasures.size(); ++k) {
    if (s.TreasureCollected(state, static_cast<int>(k))) continue;
    canvas.Diamond(map.Row(treasures[k]), map.Col(treasures[k]), 0.42, kTreasure);
  }
  const auto& buttons = map.buttons();
  for (size_t k = 0; k < buttons.size(); ++k) {
    const int row = map.Row(buttons[k]), col = map.Col(buttons[k]);
    if (s.ButtonPressed(state, static_cast<int>(k))) {
      canvas.Disk(row, col, 0.46, kButtonPressed);
    } else {
      canvas.Ring(row, col, 0.46, 0.36, kButton);
    }
  }
  for (int a = 0; a < s.num_agents(); ++a) {
    const int32_t cell = state[env::AgentIndex(a)];
    canvas.Disk(map.Row(cell), map.Col(cell), 0.32, AgentColor(a));
  }
  for (int j = 0; j < s.num_npcs(); ++j) {
    const int32_t cell = state[1 + s.num_agents() + j];
    // An entity of one cell (the prey) is a triangle; a larger one (push_box_cmae's box) fills its cells.
    bool larger = false;
    for (int other = 0; other < map.num_cells(); ++other) {
      if (other != cell && s.Covers(state, j, other)) {
        canvas.Square(map.Row(other), map.Col(other), 0.46, kNpc);
        larger = true;
      }
    }
    if (larger) {
      canvas.Square(map.Row(cell), map.Col(cell), 0.46, kNpc);
    } else {
      canvas.Triangle(map.Row(cell), map.Col(cell), kNpc);
    }
  }
  return image;
}

absl::Status WritePng(const Image& image, const std::string& path) {
  if (image.width <= 0 || image.height <= 0) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": empty image"));
  }
  png_image png;
  std::memset(&png, 0, sizeof(png));
  png.version = PNG_IMAGE_VERSION;
  png.width = static_cast<png_uint_32>(image.width);
  png.height = static_cast<png_uint_32>(image.height);
  png.format = PNG_FORMAT_RGB_COLORMAP;
  png.colormap_entries = kNumColors;
  if (!png_image_write_to_file(&png, path.c_str(), 0, image.pixels.data(), image.width, kPalette.data())) {
    const std::string message = png.message;
    png_image_free(&png);
    return absl::InternalError(absl::StrCat("cannot write PNG ", path, ": ", message));
  }
  return absl::OkStatus();
}

absl::StatusOr<std::unique_ptr<GifWriter>> GifWriter::Create(const std::string& path, int width, int height,
                                                             int delay_cs) {
  if (width <= 0 || height <= 0 || width > 65535 || height > 65535) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": bad GIF size ", width, "x", height));
  }
  if (delay_cs < 1 || delay_cs > 65535) {
    return absl::InvalidArgumentError(
        absl::StrCat(path, ": frame delay ", delay_cs, " cs not in [1, 65535]"));
  }
  // Not EGifOpenFileName: it creates files with mode 0600.
  const int fd = open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0666);
  if (fd < 0) return absl::InternalError(absl::StrCat("cannot write GIF ", path, ": ", std::strerror(errno)));
  int error = 0;
  GifFileType* gif = EGifOpenFileHandle(fd, &error);  // Owns fd from here on success.
  if (gif == nullptr) {
    close(fd);
    return absl::InternalError(absl::StrCat("cannot write GIF ", path, ": ", GifErrorString(error)));
  }
  std::unique_ptr<GifWriter> writer(new GifWriter(path, gif, width, height, delay_cs));
  // The palette padded to a power of two (32 entries, 5 bits).
  constexpr int kBits = 5;
  static_assert(kNumColors <= (1 << kBits));
  std::array<GifColorType, (1 << kBits)> colors{};
  for (int c = 0; c < kNumColors; ++c) colors[c] = {kPalette[c].r, kPalette[c].g, kPalette[c].b};
  ColorMapObject* color_map = GifMakeMapObject(1 << kBits, colors.data());
  if (color_map == nullptr) return absl::ResourceExhaustedError("GifMakeMapObject failed");
  EGifSetGifVersion(gif, true);
  const bool ok = EGifPutScreenDesc(gif, width, height, kBits, 0, color_map) == GIF_OK;  // Copies the map.
  GifFreeMapObject(color_map);
  // NETSCAPE2.0 application extension: loop forever.
  static const uint8_t kNetscape[] = "NETSCAPE2.0";
  static const uint8_t kLoopForever[] = {1, 0, 0};
  if (!ok || EGifPutExtensionLeader(gif, APPLICATION_EXT_FUNC_CODE) != GIF_OK ||
      EGifPutExtensionBlock(gif, 11, kNetscape) != GIF_OK ||
      EGifPutExtensionBlock(gif, sizeof(kLoopForever), kLoopForever) != GIF_OK ||
      EGifPutExtensionTrailer(gif) != GIF_OK) {
    return writer->Error(gif->Error);
  }
  return writer;
}

GifWriter::GifWriter(std::string path, GifFileType* gif, int width, int height, int delay_cs)
    : path_(std::move(path)), gif_(gif), width_(width), height_(height), delay_cs_(delay_cs) {}

GifWriter::~GifWriter() {
  if (gif_ != nullptr) Close().IgnoreError();
}

absl::Status GifWriter::Error(int code) const {
  return absl::InternalError(absl::StrCat("cannot write GIF ", path_, ": ", GifErrorString(code)));
}

absl::Status GifWriter::AddFrame(const Image& frame) {
  if (frame.width != width_ || frame.height != height_) {
    return absl::InvalidArgumentError(absl::StrCat(path_, ": frame of ", frame.width, "x", frame.height,
                                                   " in a GIF of ", width_, "x", height_));
  }
  if (gif_ == nullptr) return absl::FailedPreconditionError(absl::StrCat(path_, ": already closed"));
  if (!status_.ok()) return status_;
  // Only the rectangle that changed since the previous frame is stored (at
  // least one pixel, to keep the frame's delay); the rest is left in place.
  int x0 = 0, y0 = 0, x1 = width_, y1 = height_;
  if (!previous_.empty()) {
    x0 = width_, y0 = height_, x1 = 0, y1 = 0;
    for (int y = 0; y < height_; ++y) {
      for (int x = 0; x < width_; ++x) {
        const size_t i = static_cast<size_t>(y) * width_ + x;
        if (frame.pixels[i] == previous_[i]) continue;
        x0 = std::min(x0, x), x1 = std::max(x1, x + 1), y0 = std::min(y0, y), y1 = std::max(y1, y + 1);
      }
    }
    if (x1 == 0) x0 = 0, y0 = 0, x1 = 1, y1 = 1;
  }
  previous_ = frame.pixels;
  // Graphics control block: disposal "leave in place", no transparency, the delay.
  const uint8_t control[] = {0x04, static_cast<uint8_t>(delay_cs_ & 0xff),
                             static_cast<uint8_t>(delay_cs_ >> 8), 0};
  bool ok = EGifPutExtension(gif_, GRAPHICS_EXT_FUNC_CODE, sizeof(control), control) == GIF_OK &&
            EGifPutImageDesc(gif_, x0, y0, x1 - x0, y1 - y0, false, nullptr) == GIF_OK;
  for (int y = y0; ok && y < y1; ++y) {
    ok = EGifPutLine(gif_, &previous_[static_cast<size_t>(y) * width_ + x0], x1 - x0) == GIF_OK;
  }
  if (!ok) return status_ = Error(gif_->Error);
  ++num_frames_;
  return absl::OkStatus();
}

absl::Status GifWriter::Close() {
  if (gif_ == nullptr) return absl::FailedPreconditionError(absl::StrCat(path_, ": already closed"));
  int error = 0;
  if (EGifCloseFile(gif_, &error) != GIF_OK && status_.ok())
    status_ = Error(error);  // Frees gif_ either way.
  gif_ = nullptr;
  return status_;
}

absl::Status WriteGif(const std::vector<Image>& frames, const std::string& path, int delay_cs) {
  if (frames.empty()) return absl::InvalidArgumentError(absl::StrCat(path, ": no frames"));
  IMCA_ASSIGN_OR_RETURN(std::unique_ptr<GifWriter> writer,
                        GifWriter::Create(path, frames[0].width, frames[0].height, delay_cs));
  for (const Image& frame : frames) IMCA_RETURN_IF_ERROR(writer->AddFrame(frame));
  return writer->Close();
}

}  // namespace imca::envtool
