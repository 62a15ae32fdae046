#include "learner/csv_log.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "gtest/gtest.h"

namespace imca::learner {
namespace {

namespace fs = std::filesystem;

class CsvLogTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) / ("csv_log_test_" + std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  static std::string Read(const fs::path& path) {
    std::ifstream in(path);
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
  }

  fs::path dir_;
};

TEST_F(CsvLogTest, AFreshFileGetsTheHeaderThenTheRows) {
  CsvLog log((dir_ / "m.csv").string(), "iteration,x");
  ASSERT_TRUE(log.Append("1,a").ok());
  ASSERT_TRUE(log.Append("2,b").ok());
  EXPECT_EQ(Read(dir_ / "m.csv"), "iteration,x\n1,a\n2,b\n");
  EXPECT_TRUE(log.healthy());
}

TEST_F(CsvLogTest, AResumedFileDropsTheRowsOfRolledBackIterations) {
  {
    std::ofstream out(dir_ / "m.csv");
    out << "iteration,x\n1,a\n2,b\n2,b2\n3,c\n4,d\n";
  }
  // A learner restored at iteration 2 trains iteration 3 again.
  CsvLog log((dir_ / "m.csv").string(), "iteration,x");
  ASSERT_TRUE(log.Append("3,C").ok());
  ASSERT_TRUE(log.Append("3,C2").ok());  // Several rows of one key stay.
  EXPECT_EQ(Read(dir_ / "m.csv"), "iteration,x\n1,a\n2,b\n2,b2\n3,C\n3,C2\n");
}

TEST_F(CsvLogTest, AnotherVersionsFileIsSetAsideNotAppendedTo) {
  {
    std::ofstream out(dir_ / "metrics.csv");
    out << "iteration,old_column\n1,a\n";
  }
  CsvLog log((dir_ / "metrics.csv").string(), "iteration,x");
  ASSERT_TRUE(log.Append("5,e").ok());
  EXPECT_EQ(Read(dir_ / "metrics.csv"), "iteration,x\n5,e\n");
  EXPECT_EQ(Read(dir_ / "metrics.old.csv"), "iteration,old_column\n1,a\n");
}

TEST_F(CsvLogTest, AnEmptyFileGetsTheHeader) {
  std::ofstream(dir_ / "m.csv").close();
  CsvLog log((dir_ / "m.csv").string(), "iteration,x");
  ASSERT_TRUE(log.Append("1,a").ok());
  EXPECT_EQ(Read(dir_ / "m.csv"), "iteration,x\n1,a\n");
  EXPECT_FALSE(fs::exists(dir_ / "m.old.csv"));
}

TEST_F(CsvLogTest, AFailedWriteIsReportedAndTheNextRowReopens) {
  // A folder that does not exist yet: the first row fails, the second (once
  // it exists) is written under a header.
  const fs::path path = dir_ / "later" / "m.csv";
  CsvLog log(path.string(), "iteration,x");
  const absl::Status failed = log.Append("1,a");
  EXPECT_EQ(failed.code(), absl::StatusCode::kInternal);
  EXPECT_NE(failed.message().find(path.string()), std::string::npos) << failed;
  EXPECT_FALSE(log.healthy());
  fs::create_directories(path.parent_path());
  ASSERT_TRUE(log.Append("2,b").ok());
  EXPECT_TRUE(log.healthy());
  EXPECT_EQ(Read(path), "iteration,x\n2,b\n");
}

TEST_F(CsvLogTest, ARowWithoutItsKeyIsRefused) {
  CsvLog log((dir_ / "m.csv").string(), "iteration,x");
  EXPECT_EQ(log.Append("x,1").code(), absl::StatusCode::kInvalidArgument);
  EXPECT_FALSE(fs::exists(dir_ / "m.csv"));
}

}  // namespace
}  // namespace imca::learner
