#include "learner/checkpoint_store.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "common/base/atomic_file.h"
#include "gtest/gtest.h"

namespace imca::learner {
namespace {

namespace fs = std::filesystem;

// A stand-in for an algorithm's state: one line naming the version.
CheckpointStore::StateIo SaveText(const std::string& text) {
  return [text](const std::string& path) { return WriteFileAtomically(path, text); };
}

class CheckpointStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = (fs::path(::testing::TempDir()) / ("checkpoint_store_test_" + std::to_string(getpid()))).string();
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  static v1::CheckpointMeta Meta(int64_t version) {
    v1::CheckpointMeta meta;
    meta.set_version(version);
    meta.set_env_steps(100 * version);
    meta.set_wall_seconds(1.5 * version);
    meta.set_iteration(version);
    v1::CheckpointMeta::Trained* trained = meta.add_trained();
    trained->set_actor_id("actor 0");  // Ids may hold spaces.
    trained->set_incarnation(18446744073709551615ull);
    trained->set_sequence(7 * version);
    return meta;
  }

  // Restore's load, recording the state it read.
  CheckpointStore::StateIo Load(std::string* state) {
    return [state](const std::string& path) -> absl::Status {
      std::ifstream in(path);
      std::string line;
      if (!std::getline(in, line) || line.rfind("state ", 0) != 0) {
        return absl::InvalidArgumentError(absl::StrCat("damaged ", path));
      }
      *state = line;
      return absl::OkStatus();
    };
  }

  std::string dir_;
};

TEST_F(CheckpointStoreTest, SavesRestoresAndKeepsTheNewest) {
  const CheckpointStore store(dir_, /*keep=*/2);
  for (int64_t v : {1, 2, 3}) ASSERT_TRUE(store.Save(Meta(v), SaveText(absl::StrCat("state ", v))).ok());
  EXPECT_FALSE(fs::exists(dir_ + "/ckpt-00000001.meta"));
  EXPECT_FALSE(fs::exists(dir_ + "/ckpt-00000001.pt"));
  EXPECT_TRUE(fs::exists(dir_ + "/ckpt-00000002.pt"));
  EXPECT_EQ(store.Newest().value(), dir_ + "/ckpt-00000003.meta");
  std::string state;
  const absl::StatusOr<v1::CheckpointMeta> restored = store.Restore(Load(&state));
  ASSERT_TRUE(restored.ok()) << restored.status();
  EXPECT_EQ(restored->DebugString(), Meta(3).DebugString());
  EXPECT_EQ(state, "state 3");
}

TEST_F(CheckpointStoreTest, APtWithoutItsMetaIsNotACheckpoint) {
  const CheckpointStore store(dir_);
  ASSERT_TRUE(store.Save(Meta(1), SaveText("state 1")).ok());
  ASSERT_TRUE(WriteFileAtomically(dir_ + "/ckpt-00000009.pt", "state 9").ok());  // A crash before its .meta.
  EXPECT_EQ(store.Newest().value(), dir_ + "/ckpt-00000001.meta");
}

TEST_F(CheckpointStoreTest, FallsBackPastADamagedNewest) {
  const CheckpointStore store(dir_);
  for (int64_t v : {1, 2, 3}) ASSERT_TRUE(store.Save(Meta(v), SaveText(absl::StrCat("state ", v))).ok());
  ASSERT_TRUE(WriteFileAtomically(dir_ + "/ckpt-00000003.pt", "garbage").ok());
  ASSERT_TRUE(WriteFileAtomically(dir_ + "/ckpt-00000002.meta", "version: [").ok());
  std::string state;
  const absl::StatusOr<v1::CheckpointMeta> restored = store.Restore(Load(&state));
  ASSERT_TRUE(restored.ok()) << restored.status();
  EXPECT_EQ(restored->version(), 1);
  EXPECT_EQ(state, "state 1");
}

TEST_F(CheckpointStoreTest, NoneThatLoadsGivesTheNewestsError) {
  const CheckpointStore store(dir_);
  ASSERT_TRUE(store.Save(Meta(1), SaveText("garbage")).ok());
  ASSERT_TRUE(store.Save(Meta(2), SaveText("garbage")).ok());
  std::string state;
  const absl::StatusOr<v1::CheckpointMeta> restored = store.Restore(Load(&state));
  EXPECT_EQ(restored.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(restored.status().message().find("ckpt-00000002.pt"), std::string::npos) << restored.status();
}

TEST_F(CheckpointStoreTest, AnEmptyOrMissingFolderHoldsNone) {
  std::string state;
  EXPECT_EQ(CheckpointStore(dir_).Restore(Load(&state)).status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(CheckpointStore(dir_ + "/missing").Newest().status().code(), absl::StatusCode::kNotFound);
}

TEST_F(CheckpointStoreTest, MetadataOfEarlierVersionsStillRestores) {
  // The "key value" lines written before CheckpointMeta.
  ASSERT_TRUE(WriteFileAtomically(dir_ + "/ckpt-00000004.pt", "state 4").ok());
  ASSERT_TRUE(WriteFileAtomically(dir_ + "/ckpt-00000004.meta",
                                  "version 4\nenv_steps 400\nwall_seconds 6\niteration 4\n"
                                  "accepted 18446744073709551615 28 actor 0\n")
                  .ok());
  std::string state;
  const absl::StatusOr<v1::CheckpointMeta> restored = CheckpointStore(dir_).Restore(Load(&state));
  ASSERT_TRUE(restored.ok()) << restored.status();
  EXPECT_EQ(restored->DebugString(), Meta(4).DebugString());
}

TEST_F(CheckpointStoreTest, NegativeCountsAreRefused) {
  ASSERT_TRUE(WriteFileAtomically(dir_ + "/ckpt-00000001.pt", "state 1").ok());
  ASSERT_TRUE(WriteFileAtomically(dir_ + "/ckpt-00000001.meta", "version: 1 env_steps: -5").ok());
  std::string state;
  const absl::StatusOr<v1::CheckpointMeta> restored = CheckpointStore(dir_).Restore(Load(&state));
  EXPECT_EQ(restored.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(state.empty());
}

TEST_F(CheckpointStoreTest, ResumeFolderFromTheFlags) {
  EXPECT_EQ(ResumeFolder("/some/dir", false, "").value(), "/some/dir");
  EXPECT_EQ(ResumeFolder("", false, dir_).value(), "");
  EXPECT_EQ(ResumeFolder("/some/dir", true, dir_).status().message(), "--auto_resume and --resume exclude each other");
  EXPECT_EQ(ResumeFolder("", true, "").status().message(), "--auto_resume needs --run_dir");
  EXPECT_EQ(ResumeFolder("", true, dir_).value(), "");  // Nothing to resume: start fresh.
  const CheckpointStore store(dir_ + "/checkpoints");
  fs::create_directories(store.dir());
  ASSERT_TRUE(store.Save(Meta(1), SaveText("state 1")).ok());
  EXPECT_EQ(ResumeFolder("", true, dir_).value(), store.dir());
}

}  // namespace
}  // namespace imca::learner
