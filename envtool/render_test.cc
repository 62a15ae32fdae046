#include "envtool/render.h"

#include <gif_lib.h>
#include <png.h>

#include <cstring>
#include <memory>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "common/env/env.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace imca::envtool {
namespace {

using ::testing::HasSubstr;

std::unique_ptr<env::Scenario> Make(const std::string& name, const char* text) {
  auto map = env::GridMap::Parse(text, name + "_test_map");
  EXPECT_TRUE(map.ok()) << map.status();
  env::ScenarioConfig config;
  config.name = name;
  auto scenario = env::MakeScenarioWithMap(config, *std::move(map));
  EXPECT_TRUE(scenario.ok()) << scenario.status();
  return *std::move(scenario);
}

// A PNG decoded to RGB with libpng.
struct Decoded {
  int width = 0;
  int height = 0;
  std::vector<uint8_t> rgb;
  Rgb at(int x, int y) const {
    const uint8_t* p = &rgb[3 * (static_cast<size_t>(y) * width + x)];
    return {p[0], p[1], p[2]};
  }
};

Decoded ReadPng(const std::string& path) {
  png_image png;
  std::memset(&png, 0, sizeof(png));
  png.version = PNG_IMAGE_VERSION;
  Decoded out;
  if (!png_image_begin_read_from_file(&png, path.c_str())) {
    ADD_FAILURE() << path << ": " << png.message;
    return out;
  }
  png.format = PNG_FORMAT_RGB;
  out.width = static_cast<int>(png.width);
  out.height = static_cast<int>(png.height);
  out.rgb.resize(PNG_IMAGE_SIZE(png));
  if (!png_image_finish_read(&png, nullptr, out.rgb.data(), 0, nullptr)) {
    ADD_FAILURE() << path << ": " << png.message;
  }
  return out;
}

// Renders `state` to a PNG and decodes it again.
Decoded RoundTrip(const env::Scenario& s, const std::vector<int32_t>& state, int cell_px,
                  const std::string& name) {
  EXPECT_TRUE(s.ValidateState(state.data()).ok()) << s.ValidateState(state.data());
  auto renderer = Renderer::Create(&s, cell_px);
  EXPECT_TRUE(renderer.ok()) << renderer.status();
  const std::string path = ::testing::TempDir() + "/" + name + ".png";
  const absl::Status written = WritePng(renderer->Draw(state.data()), path);
  EXPECT_TRUE(written.ok()) << written;
  return ReadPng(path);
}

// Colour at the centre of `cell`, or `dx` cells right of it.
Rgb Centre(const Decoded& image, const env::GridMap& map, int cell, int cell_px, double dx = 0) {
  return image.at(map.Col(cell) * cell_px + cell_px / 2 + static_cast<int>(dx * cell_px),
                  map.Row(cell) * cell_px + cell_px / 2);
}

// multi_room: door A (cell 22) with its switch 'a' at cell 12; the treasure
// (cell 16) makes the right room the goal room.
constexpr char kRooms[] =
    "#########\n"   //  0.. 8
    "#1.a#..T#\n"   //  9..17
    "#2..A...#\n"   // 18..26
    "#########\n";  // 27..35

TEST(RendererTest, PngShowsWallsFloorAgentsDoorsSwitchesAndTreasures) {
  auto s = Make("multi_room", kRooms);
  const env::GridMap& map = s->map();
  for (int px : {24, 10}) {
    const Decoded closed = RoundTrip(*s, {0, 10, 19, 0}, px, "rooms_closed");
    ASSERT_EQ(closed.width, 9 * px);
    ASSERT_EQ(closed.height, 4 * px);
    EXPECT_EQ(Centre(closed, map, 0, px), PaletteRgb(kWall));
    EXPECT_EQ(Centre(closed, map, 11, px), PaletteRgb(kFloor));
    EXPECT_EQ(Centre(closed, map, 24, px), PaletteRgb(kGoalRoom));
    EXPECT_EQ(Centre(closed, map, 10, px), PaletteRgb(AgentColor(0)));
    EXPECT_EQ(Centre(closed, map, 19, px), PaletteRgb(AgentColor(1)));
    EXPECT_EQ(Centre(closed, map, 12, px), PaletteRgb(DoorColor(0)));  // The switch.
    EXPECT_EQ(Centre(closed, map, 22, px), PaletteRgb(kDoorClosed));
    EXPECT_EQ(Centre(closed, map, 16, px), PaletteRgb(kTreasure));
    // Agent 1 on the switch opens the door (z bit 0).
    const Decoded open = RoundTrip(*s, {1, 12, 19, 1}, px, "rooms_open");
    EXPECT_EQ(Centre(open, map, 22, px), PaletteRgb(kDoorOpen));
    EXPECT_EQ(Centre(open, map, 12, px), PaletteRgb(AgentColor(0)));
    EXPECT_EQ(Centre(open, map, 10, px), PaletteRgb(kFloor));
  }
}

TEST(RendererTest, PaletteColoursAreDistinct) {
  std::set<std::tuple<int, int, int>> seen;
  for (int c = 0; c < kNumColors; ++c) {
    const Rgb rgb = PaletteRgb(static_cast<uint8_t>(c));
    EXPECT_TRUE(seen.insert({rgb.r, rgb.g, rgb.b}).second) << "colour " << c;
  }
}

TEST(RendererTest, CollectedTreasureDisappears) {
  auto s = Make("coop_nav",
                "#######\n"    //  0.. 6
                "#1.T.2#\n"    //  7..13
                "#######\n");  // 14..20
  const Decoded before = RoundTrip(*s, {0, 8, 12, 0}, 24, "coop_before");
  EXPECT_EQ(Centre(before, s->map(), 10, 24), PaletteRgb(kTreasure));
  EXPECT_EQ(Centre(before, s->map(), 9, 24), PaletteRgb(kFloor));  // No doors: no goal room tint.
  const Decoded after = RoundTrip(*s, {1, 8, 12, 2}, 24, "coop_after");
  EXPECT_EQ(Centre(after, s->map(), 10, 24), PaletteRgb(kFloor));
}

TEST(RendererTest, ButtonIsARingFilledWhilePressed) {
  auto s = Make("twin_buttons",
                "#####\n"    //  0.. 4
                "#X.X#\n"    //  5.. 9
                "#1.2#\n"    // 10..14
                "#####\n");  // 15..19
  std::vector<int32_t> state = {0, 11, 13, 0};
  const Decoded released = RoundTrip(*s, state, 24, "buttons_released");
  EXPECT_EQ(Centre(released, s->map(), 6, 24), PaletteRgb(kFloor));
  EXPECT_EQ(Centre(released, s->map(), 6, 24, 0.41), PaletteRgb(kButton));
  Rng rng(1);
  std::vector<float> rewards(2);
  const int32_t actions[] = {env::kUp, env::kStay};
  s->Step(state.data(), actions, rng, rewards.data());
  const Decoded pressed = RoundTrip(*s, state, 24, "buttons_pressed");
  EXPECT_EQ(Centre(pressed, s->map(), 6, 24), PaletteRgb(AgentColor(0)));
  EXPECT_EQ(Centre(pressed, s->map(), 6, 24, 0.41), PaletteRgb(kButtonPressed));
  EXPECT_EQ(Centre(pressed, s->map(), 8, 24, 0.41), PaletteRgb(kButton));
}

TEST(RendererTest, PreyIsRedOnTheTintedZone) {
  auto s = Make("predator_prey",
                "ZZZZ\n"    // 0..3
                "....\n"    // 4..7
                "SSSS\n");  // 8..11
  const Decoded image = RoundTrip(*s, {0, 8, 9, 10, 11, 1, 0}, 24, "prey");
  EXPECT_EQ(Centre(image, s->map(), 1, 24), PaletteRgb(kNpc));
  EXPECT_EQ(Centre(image, s->map(), 2, 24), PaletteRgb(kPreyZone));
  EXPECT_EQ(Centre(image, s->map(), 5, 24), PaletteRgb(kFloor));
  for (int a = 0; a < 4; ++a) EXPECT_EQ(Centre(image, s->map(), 8 + a, 24), PaletteRgb(AgentColor(a)));
}

TEST(RendererTest, BadCellSizeIsRejected) {
  auto s = Make("multi_room", kRooms);
  EXPECT_EQ(Renderer::Create(s.get(), 3).status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(Renderer::Create(s.get(), 65).status().code(), absl::StatusCode::kInvalidArgument);
}

TEST(WriteTest, GifHoldsEveryFrameAtTheImageSize) {
  auto s = Make("multi_room", kRooms);
  auto renderer = Renderer::Create(s.get(), 12);
  ASSERT_TRUE(renderer.ok());
  std::vector<int32_t> state = {0, 10, 19, 0};
  std::vector<Image> frames = {renderer->Draw(state.data())};
  Rng rng(1);
  std::vector<float> rewards(2);
  const int32_t actions[] = {env::kRight, env::kRight};
  for (int k = 0; k < 2; ++k) {
    s->Step(state.data(), actions, rng, rewards.data());
    frames.push_back(renderer->Draw(state.data()));
  }
  const std::string path = ::testing::TempDir() + "/episode.gif";
  ASSERT_TRUE(WriteGif(frames, path, 30).ok());

  int error = 0;
  GifFileType* gif = DGifOpenFileName(path.c_str(), &error);
  ASSERT_NE(gif, nullptr) << GifErrorString(error);
  ASSERT_EQ(DGifSlurp(gif), GIF_OK) << GifErrorString(gif->Error);
  EXPECT_EQ(gif->ImageCount, 3);
  EXPECT_EQ(gif->SWidth, 9 * 12);
  EXPECT_EQ(gif->SHeight, 4 * 12);
  // Frames after the first store only the rectangle that changed: paint
  // each onto the previous picture and compare.
  std::vector<uint8_t> picture(frames[0].pixels.size());
  for (int f = 0; f < gif->ImageCount; ++f) {
    const GifImageDesc& desc = gif->SavedImages[f].ImageDesc;
    if (f == 0) {
      EXPECT_EQ(desc.Width * desc.Height, static_cast<int>(picture.size()));
    } else {
      EXPECT_LT(desc.Width * desc.Height, static_cast<int>(picture.size()) / 4) << "frame " << f;
    }
    for (int y = 0; y < desc.Height; ++y) {
      std::memcpy(&picture[(desc.Top + y) * 9 * 12 + desc.Left],
                  &gif->SavedImages[f].RasterBits[y * desc.Width], desc.Width);
    }
    EXPECT_EQ(picture, frames[f].pixels) << "frame " << f;
  }
  GraphicsControlBlock control;
  ASSERT_EQ(DGifSavedExtensionToGCB(gif, 2, &control), GIF_OK);
  EXPECT_EQ(control.DelayTime, 30);
  const GifColorType wall = gif->SColorMap->Colors[kWall];
  EXPECT_EQ((Rgb{wall.Red, wall.Green, wall.Blue}), PaletteRgb(kWall));
  DGifCloseFile(gif, &error);
}

TEST(WriteTest, GifWriterStreamsFramesOfItsSize) {
  const std::string path = ::testing::TempDir() + "/stream.gif";
  auto writer = GifWriter::Create(path, 2, 1, 5);
  ASSERT_TRUE(writer.ok()) << writer.status();
  EXPECT_TRUE((*writer)->AddFrame(Image{2, 1, {kWall, kFloor}}).ok());
  EXPECT_EQ((*writer)->AddFrame(Image{1, 2, {kWall, kFloor}}).code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE((*writer)->AddFrame(Image{2, 1, {kFloor, kWall}}).ok());
  EXPECT_EQ((*writer)->num_frames(), 2);
  EXPECT_TRUE((*writer)->Close().ok());
  EXPECT_EQ((*writer)->Close().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_EQ(GifWriter::Create(path, 2, 1, 0).status().code(), absl::StatusCode::kInvalidArgument);
}

TEST(WriteTest, ErrorsNameThePath) {
  Image image{2, 2, std::vector<uint8_t>(4, kWall)};
  const absl::Status png = WritePng(image, "/nonexistent_dir/a.png");
  EXPECT_EQ(png.code(), absl::StatusCode::kInternal);
  EXPECT_THAT(png.message(), HasSubstr("/nonexistent_dir/a.png"));
  const absl::Status gif = WriteGif({image}, "/nonexistent_dir/a.gif", 10);
  EXPECT_EQ(gif.code(), absl::StatusCode::kInternal);
  EXPECT_THAT(gif.message(), HasSubstr("/nonexistent_dir/a.gif"));
  const std::string path = ::testing::TempDir() + "/mixed.gif";
  EXPECT_EQ(WriteGif({}, path, 10).code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(WriteGif({image, Image{1, 1, {kWall}}}, path, 10).code(), absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace imca::envtool
