#include "common/base/settings.h"

#include <string>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace imca {
namespace {

using ::testing::ElementsAre;

std::vector<std::string> Bare(std::vector<std::string> args) {
  std::vector<char*> argv = ArgvOf(args);
  return BareBooleanFlags(static_cast<int>(args.size()), argv.data(), {"deterministic", "edti"});
}

TEST(SettingsTest, BareBooleansAreSpelledOutAndTheRestIsKept) {
  EXPECT_THAT(Bare({"learner", "--deterministic", "-edti", "--nodeterministic", "--seed", "3"}),
              ElementsAre("learner", "--deterministic=true", "--edti=true", "--deterministic=false", "--seed", "3"));
  // Given values, other flags, "no" of an unknown name and everything after
  // "--" are as given.
  EXPECT_THAT(Bare({"learner", "--edti=false", "--nothing", "--notes", "--", "--deterministic"}),
              ElementsAre("learner", "--edti=false", "--nothing", "--notes", "--", "--deterministic"));
}

enum class Shape { kRound, kSquare };
std::vector<std::string> SettingChoices(Shape) { return {"round", "square"}; }
std::string AbslUnparseFlag(Shape s) { return s == Shape::kRound ? "round" : "square"; }

TEST(SettingsTest, RowsAndJsonFollowTheType) {
  EXPECT_EQ(MakeSettingRow<bool>("b", "h").type, "bool");
  EXPECT_EQ(MakeSettingRow<int64_t>("i", "h").type, "int");
  EXPECT_EQ(MakeSettingRow<float>("f", "h").type, "float");
  EXPECT_EQ(MakeSettingRow<std::string>("s", "h").type, "string");
  const SettingRow shape = MakeSettingRow<Shape>("shape", "h");
  EXPECT_EQ(shape.type, "enum");
  EXPECT_THAT(shape.choices, ElementsAre("round", "square"));
  JsonObject json;
  AddSetting(&json, "b", true);
  AddSetting(&json, "f", 0.1f);
  AddSetting(&json, "d", 0.1);
  AddSetting(&json, "u", uint64_t{18446744073709551615u});
  AddSetting(&json, "shape", Shape::kSquare);
  AddSetting(&json, "s", std::string("x"));
  // Floats as the shortest text that reads back as the same float.
  EXPECT_EQ(json.Text(),
            R"({"b": true, "f": 0.1, "d": 0.1, "u": 18446744073709551615, "shape": "square", "s": "x"})");
  EXPECT_EQ(SettingRowsJson({shape}),
            R"([{"name": "shape", "type": "enum", "help": "h", "choices": ["round", "square"], "owner": ""}])");
}

}  // namespace
}  // namespace imca
