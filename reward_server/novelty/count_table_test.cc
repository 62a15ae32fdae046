#include "reward_server/novelty/count_table.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace imca::reward {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

TEST(CountTableTest, EqualTablesWriteEqualBytesWhateverTheirHistory) {
  // Other insertion orders and capacities: other hash-map orders.
  CountTable up, down;
  down.Reserve(1 << 16);
  for (uint64_t key = 0; key < 1000; ++key) up.Add(key * 7919, static_cast<uint32_t>(key + 1));
  for (uint64_t key = 1000; key-- > 0;) down.Add(key * 7919, static_cast<uint32_t>(key + 1));
  std::ostringstream a, b;
  ASSERT_TRUE(up.Write(a).ok());
  ASSERT_TRUE(down.Write(b).ok());
  EXPECT_EQ(a.str(), b.str());
  // And it reads back as the same table.
  CountTable back;
  std::istringstream in(a.str());
  ASSERT_TRUE(back.Read(in).ok());
  EXPECT_EQ(back.size(), 1000);
  EXPECT_EQ(back.Get(999 * 7919), 1000u);
}

constexpr char kTag[] = "test-tag";

class CountStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = ::testing::TempDir() + "/count_store_test_" + std::to_string(getpid());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    path_ = dir_ + "/snapshot.bin";
  }
  void TearDown() override { fs::remove_all(dir_); }

  // One Score call's worth: `keys` increments of table 0, `keys` / 2 of 1.
  static void Score(CountStore& store, uint64_t first_key, int keys) {
    for (int i = 0; i < keys; ++i) store.Increment(0, first_key + i);
    for (int i = 0; i < keys / 2; ++i) store.Add(1, first_key + i, 3);
    ASSERT_TRUE(store.Commit(keys).ok());
  }

  static int64_t Sum(const CountStore& store, int table, uint64_t first_key, int keys) {
    int64_t sum = 0;
    for (int i = 0; i < keys; ++i) sum += store.Get(table, first_key + i);
    return sum;
  }

  std::vector<std::string> Journals() const {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(dir_)) {
      const std::string name = entry.path().filename().string();
      if (name.find(".journal-") != std::string::npos) names.push_back(name);
    }
    std::sort(names.begin(), names.end());
    return names;
  }

  std::string dir_, path_;
};

TEST_F(CountStoreTest, AKilledStoreLosesNoCommittedIncrement) {
  {
    CountStore store(2);
    ASSERT_TRUE(store.Restore(path_, kTag).ok());  // Nothing yet: starts journaling.
    Score(store, 100, 10);
    Score(store, 105, 10);  // Overlaps: keys 105..109 counted twice.
    // No snapshot, no shutdown: the process "dies" here.
  }
  CountStore restarted(2);
  ASSERT_TRUE(restarted.Restore(path_, kTag).ok());
  EXPECT_EQ(restarted.transitions(), 20);
  EXPECT_EQ(restarted.Get(0, 104), 1u);
  EXPECT_EQ(restarted.Get(0, 107), 2u);
  EXPECT_EQ(Sum(restarted, 0, 100, 20), 20);
  EXPECT_EQ(Sum(restarted, 1, 100, 20), 2 * 5 * 3);
  EXPECT_EQ(restarted.table(0).size(), 15);
}

TEST_F(CountStoreTest, SnapshotsFoldTheJournalAndRecoveryCountsEachIncrementOnce) {
  CountStore store(2);
  ASSERT_TRUE(store.Restore(path_, kTag).ok());
  Score(store, 0, 8);
  CountStore::Snapshot snapshot = store.TakeSnapshot().value();
  Score(store, 0, 8);  // After the copy: goes to the next epoch's journal.
  // A crash before the snapshot is written: the old snapshot (none) and both
  // journals hold everything.
  {
    CountStore crashed(2);
    ASSERT_TRUE(crashed.Restore(path_, kTag).ok());
    EXPECT_EQ(Sum(crashed, 0, 0, 8), 16);
    EXPECT_EQ(crashed.transitions(), 16);
  }
  const std::vector<std::string> before = Journals();
  ASSERT_TRUE(CountStore::WriteSnapshot(path_, kTag, snapshot).ok());
  // The journals the snapshot covers are gone; the newer ones stay.
  EXPECT_LT(Journals().size(), before.size());
  Score(store, 0, 8);
  CountStore restarted(2);
  ASSERT_TRUE(restarted.Restore(path_, kTag).ok());
  EXPECT_EQ(Sum(restarted, 0, 0, 8), 24);
  EXPECT_EQ(restarted.transitions(), 24);
  // A journal the snapshot covers that survived (a crash between writing
  // the snapshot and deleting it) is not replayed twice.
  CountStore::Snapshot second = restarted.TakeSnapshot().value();
  const std::vector<std::string> covered = Journals();
  std::vector<std::string> copies;
  for (const std::string& name : covered) {
    fs::copy_file(dir_ + "/" + name, dir_ + "/" + name + ".keep");
    copies.push_back(name);
  }
  ASSERT_TRUE(CountStore::WriteSnapshot(path_, kTag, second).ok());
  for (const std::string& name : copies) {
    if (!fs::exists(dir_ + "/" + name)) fs::rename(dir_ + "/" + name + ".keep", dir_ + "/" + name);
  }
  CountStore again(2);
  ASSERT_TRUE(again.Restore(path_, kTag).ok());
  EXPECT_EQ(Sum(again, 0, 0, 8), 24);
  EXPECT_EQ(again.transitions(), 24);
}

TEST_F(CountStoreTest, ATornRecordIsTheOnlyOneLost) {
  {
    CountStore store(2);
    ASSERT_TRUE(store.Restore(path_, kTag).ok());
    Score(store, 0, 4);
    Score(store, 0, 4);
  }
  const std::vector<std::string> journals = Journals();
  ASSERT_EQ(journals.size(), 1u);
  const std::string journal = dir_ + "/" + journals[0];
  // A kill in the middle of the second record's write.
  fs::resize_file(journal, fs::file_size(journal) - 5);
  CountStore restarted(2);
  ASSERT_TRUE(restarted.Restore(path_, kTag).ok());
  EXPECT_EQ(Sum(restarted, 0, 0, 4), 4);
  EXPECT_EQ(restarted.transitions(), 4);
  // A flipped byte inside the first record is caught by its checksum: the
  // journal is read up to it.
  {
    std::fstream f(journal, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(std::string("IMCA-JOURNAL-1 test-tag\n").size() + 16 + 10);
    f.put('\x7f');
  }
  CountStore corrupt(2);
  ASSERT_TRUE(corrupt.Restore(path_, kTag).ok());
  EXPECT_EQ(corrupt.transitions(), 0);
  EXPECT_EQ(corrupt.table(0).size(), 0);
}

TEST_F(CountStoreTest, OtherConfigurationsAndDamageAreRefused) {
  {
    CountStore store(2);
    ASSERT_TRUE(store.Restore(path_, kTag).ok());
    Score(store, 0, 2);
  }
  CountStore other(2);
  const absl::Status refused = other.Restore(path_, "another-tag");
  EXPECT_EQ(refused.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(std::string(refused.message()), HasSubstr("not by this configuration"));
  // A snapshot cut short is DATA_LOSS, and nothing changes.
  CountStore store(2);
  ASSERT_TRUE(store.Restore(path_, kTag).ok());
  ASSERT_TRUE(CountStore::WriteSnapshot(path_, kTag, store.TakeSnapshot().value()).ok());
  fs::resize_file(path_, fs::file_size(path_) - 4);
  CountStore damaged(2);
  EXPECT_EQ(damaged.Restore(path_, kTag).code(), absl::StatusCode::kDataLoss);
  EXPECT_EQ(damaged.table(0).size(), 0);
}

}  // namespace
}  // namespace imca::reward
