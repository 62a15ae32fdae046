#include "common/base/side_thread.h"

#include <atomic>
#include <stdexcept>
#include <string>
#include <thread>

#include "gtest/gtest.h"

namespace imca {
namespace {

TEST(SideThreadTest, RunsTasksInTurnOnItsOwnThreadAfterOnStart) {
  thread_local int setting = 0;
  int seen = -1;
  std::thread::id ran_on;
  SideThread side([] { setting = 7; });
  side.Start([&] {
    seen = setting;
    ran_on = std::this_thread::get_id();
  });
  EXPECT_EQ(side.Wait(), nullptr);
  EXPECT_EQ(seen, 7);  // on_start ran on the side thread, before the task.
  EXPECT_NE(ran_on, std::this_thread::get_id());
  int count = 0;
  for (int i = 0; i < 100; ++i) side.Start([&] { ++count; });  // Each Start waits for the last task.
  side.Join();
  EXPECT_EQ(count, 100);
}

TEST(SideThreadTest, WhatATaskThrowsComesBackOnceAndJoinRethrowsIt) {
  SideThread side;
  side.Start([] { throw std::runtime_error("boom"); });
  std::exception_ptr error = side.Wait();
  ASSERT_NE(error, nullptr);
  EXPECT_THROW(std::rethrow_exception(error), std::runtime_error);
  EXPECT_EQ(side.Wait(), nullptr);  // Returned once.
  side.Start([] { throw std::logic_error("again"); });
  EXPECT_THROW(side.Join(), std::logic_error);
  side.Start([] {});
  EXPECT_NO_THROW(side.Join());
}

TEST(SideThreadTest, TheDestructorRunsAStartedTaskThenJoins) {
  std::atomic<bool> ran{false};
  {
    SideThread side;
    side.Start([&] { ran = true; });
  }
  EXPECT_TRUE(ran);
}

}  // namespace
}  // namespace imca
