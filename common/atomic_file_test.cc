#include "common/atomic_file.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>

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

}  // namespace
}  // namespace imca
