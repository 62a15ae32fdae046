#include "common/base/atomic_file.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "common/base/json.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace imca {
namespace {

using ::testing::HasSubstr;

std::string Read(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

class AtomicFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = ::testing::TempDir() + "/atomic_file_test_" + std::to_string(getpid());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    path_ = dir_ + "/state.bin";
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  std::string dir_, path_;
};

TEST_F(AtomicFileTest, WritesAndReplacesWhole) {
  ASSERT_TRUE(WriteFileAtomically(path_, "first").ok());
  EXPECT_EQ(Read(path_), "first");
  ASSERT_TRUE(WriteFileAtomically(path_, std::string(1 << 20, 'x')).ok());
  EXPECT_EQ(Read(path_).size(), size_t{1} << 20);
  EXPECT_FALSE(std::filesystem::exists(path_ + ".tmp"));
}

TEST_F(AtomicFileTest, AWriterThatFailsHalfwayChangesNothing) {
  ASSERT_TRUE(WriteFileAtomically(path_, "old contents").ok());
  const absl::Status status = WriteFileAtomically(path_, [](std::ostream& out) {
    out << "half of the new";
    return absl::DataLossError("disk gone");
  });
  EXPECT_EQ(status.code(), absl::StatusCode::kDataLoss);
  EXPECT_EQ(Read(path_), "old contents");
  EXPECT_FALSE(std::filesystem::exists(path_ + ".tmp"));
}

TEST_F(AtomicFileTest, AnUnwritablePlaceIsAnErrorNamingIt) {
  const std::string missing = dir_ + "/no/such/folder/state.bin";
  const absl::Status status = WriteFileAtomically(missing, "x");
  EXPECT_EQ(status.code(), absl::StatusCode::kInternal);
  EXPECT_THAT(std::string(status.message()), HasSubstr(missing + ".tmp"));
  // A folder where the file should be: the rename fails, the folder stays.
  std::filesystem::create_directories(path_);
  std::ofstream(path_ + "/inside") << "keep";
  EXPECT_EQ(WriteFileAtomically(path_, "x").code(), absl::StatusCode::kInternal);
  EXPECT_EQ(Read(path_ + "/inside"), "keep");
  EXPECT_FALSE(std::filesystem::exists(path_ + ".tmp"));
}

TEST(JsonObjectTest, KeepsKeyOrderAndEscapesStrings) {
  JsonObject o;
  o.Add("id", "a\"b\\c\n").Add("n", int64_t{-3}).Add("ok", true).Add("x", 0.5, 3).Add("names", {"p", "q"});
  EXPECT_EQ(o.Text(), R"({"id": "a\"b\\c\u000a", "n": -3, "ok": true, "x": 0.500, "names": ["p", "q"]})");
  EXPECT_EQ(JsonObject().Text(), "{}");
  EXPECT_EQ(JsonObject().Raw("o", JsonObject().Add("k", 1).Text()).Text(), R"({"o": {"k": 1}})");
}

}  // namespace
}  // namespace imca
