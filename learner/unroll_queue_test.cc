#include "learner/unroll_queue.h"

#include <atomic>
#include <chrono>
#include <string>
#include <thread>
#include <utility>

#include "gtest/gtest.h"
#include "learner/push_testing.h"

namespace imca::learner {
namespace {

// A small stand-in unroll: 4 steps x 2 envs = 8 joint steps.
v1::Unroll Unroll(int64_t version, const std::string& actor = "a", uint64_t incarnation = 1, int64_t sequence = 1) {
  v1::Unroll u;
  u.set_length(4);
  u.set_num_envs(2);
  u.set_policy_version(version);
  u.set_actor_id(actor);
  u.set_incarnation(incarnation);
  u.set_sequence(sequence);
  return u;
}

class UnrollQueueTest : public ::testing::Test {
 protected:
  UnrollQueue::Options Options() {
    UnrollQueue::Options o;
    o.capacity = 4;
    o.max_policy_lag = 1;
    o.max_actor_ids = 3;
    o.validate = [](const v1::Unroll& u) {
      return u.length() > 0 ? PushOutcome() : Refused(v1::REJECTION_INVALID, "unroll.length must be > 0");
    };
    o.featurise = [](v1::Unroll u) { return FeaturisedUnroll{std::move(u), {1.0f}, {}, 0}; };
    o.on_accept = [this](const v1::Unroll&) { ++accepted_; };
    return o;
  }

  static void WaitForBlockedPusher(const UnrollQueue& q) {
    while (q.stats().pushers_waiting == 0) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }

  int accepted_ = 0;
};

TEST_F(UnrollQueueTest, QueuesValidUnrollsInOrderWithTheirFeatures) {
  UnrollQueue q(Options());
  ASSERT_TRUE(Accepted(q.Push(Unroll(0, "a", 1, 1))));
  ASSERT_TRUE(Accepted(q.Push(Unroll(0, "b", 1, 1))));
  const UnrollQueue::Stats s = q.stats();
  EXPECT_EQ(s.received, 2);
  EXPECT_EQ(s.depth, 2);
  EXPECT_EQ(s.queued_steps, 16);
  EXPECT_EQ(s.incarnations, 2);
  EXPECT_EQ(accepted_, 2);
  int dropped = 0;
  const std::optional<FeaturisedUnroll> first = q.Next(&dropped);
  ASSERT_TRUE(first.has_value());
  EXPECT_EQ(first->unroll.actor_id(), "a");
  EXPECT_EQ(first->obs, std::vector<float>{1.0f});
  EXPECT_EQ(q.stats().queued_steps, 8);
  EXPECT_EQ(dropped, 0);
}

TEST_F(UnrollQueueTest, RefusesEachReasonWithItsCodeAndCountsIt) {
  UnrollQueue q(Options());
  v1::Unroll invalid = Unroll(0);
  invalid.set_length(0);
  EXPECT_EQ(RejectionOf(q.Push(invalid)), v1::REJECTION_INVALID);
  EXPECT_EQ(RejectionOf(q.Push(Unroll(1))), v1::REJECTION_AHEAD);  // Ahead of version 0.
  ASSERT_TRUE(Accepted(q.Push(Unroll(0, "a", 1, 5))));
  EXPECT_EQ(RejectionOf(q.Push(Unroll(0, "a", 1, 5))), v1::REJECTION_DUPLICATE);
  EXPECT_EQ(RejectionOf(q.Push(Unroll(0, "a", 1, 4))), v1::REJECTION_DUPLICATE);
  ASSERT_TRUE(Accepted(q.Push(Unroll(0, "a", 2, 1))));  // A restarted actor starts its sequence again.
  ASSERT_TRUE(Accepted(q.Push(Unroll(0, "b"))));
  ASSERT_TRUE(Accepted(q.Push(Unroll(0, "c"))));
  EXPECT_EQ(RejectionOf(q.Push(Unroll(0, "d"))), v1::REJECTION_OVER_CAP);  // A fourth id.
  q.NewVersion(2);
  EXPECT_EQ(RejectionOf(q.Push(Unroll(0, "a", 2, 2))), v1::REJECTION_STALE);  // 2 behind, lag 1.
  const UnrollQueue::Stats s = q.stats();
  EXPECT_EQ(s.rejected, 3);
  EXPECT_EQ(s.duplicate, 2);
  EXPECT_EQ(s.stale, 1);
  EXPECT_EQ(s.received, 4);
  EXPECT_EQ(s.incarnations, 4);
  EXPECT_EQ(s.actor_ids, 3);
  EXPECT_EQ(q.ActorIds(), (std::vector<std::string>{"a", "b", "c"}));
}

TEST_F(UnrollQueueTest, NextDropsWhatAgedPastTheLagWhileQueued) {
  UnrollQueue q(Options());
  ASSERT_TRUE(Accepted(q.Push(Unroll(0, "a", 1, 1))));
  ASSERT_TRUE(Accepted(q.Push(Unroll(0, "a", 1, 2))));
  q.NewVersion(1);
  ASSERT_TRUE(Accepted(q.Push(Unroll(1, "a", 1, 3))));
  q.NewVersion(2);
  int dropped = 0;
  const std::optional<FeaturisedUnroll> next = q.Next(&dropped);
  ASSERT_TRUE(next.has_value());
  EXPECT_EQ(next->unroll.sequence(), 3);
  EXPECT_EQ(dropped, 2);
  EXPECT_EQ(q.stats().stale, 2);
}

TEST_F(UnrollQueueTest, AnOffPolicyQueueTakesAnyAge) {
  UnrollQueue::Options o = Options();
  o.max_policy_lag = std::nullopt;
  UnrollQueue q(std::move(o));
  q.NewVersion(100);
  ASSERT_TRUE(Accepted(q.Push(Unroll(0))));
  int dropped = 0;
  EXPECT_TRUE(q.Next(&dropped).has_value());
}

TEST_F(UnrollQueueTest, ASynchronousQueueTakesOneBatchOfTheCurrentVersion) {
  UnrollQueue::Options o = Options();
  o.synchronous = true;
  o.batch_steps = 16;
  UnrollQueue q(std::move(o));
  ASSERT_TRUE(Accepted(q.Push(Unroll(0, "a", 1, 1))));
  ASSERT_TRUE(Accepted(q.Push(Unroll(0, "a", 1, 2))));
  const absl::StatusOr<PushOutcome> full = q.Push(Unroll(0, "a", 1, 3));
  EXPECT_EQ(RejectionOf(full), v1::REJECTION_STALE);
  EXPECT_NE(Why(full).find("is full"), std::string::npos) << Why(full);
  q.NewVersion(1);
  EXPECT_EQ(RejectionOf(q.Push(Unroll(0, "a", 1, 3))), v1::REJECTION_STALE);  // Not the current one.
  EXPECT_TRUE(Accepted(q.Push(Unroll(1, "a", 1, 3))));
}

TEST_F(UnrollQueueTest, AFullQueueBlocksUntilTheTrainerTakes) {
  UnrollQueue::Options o = Options();
  o.capacity = 1;
  UnrollQueue q(std::move(o));
  ASSERT_TRUE(Accepted(q.Push(Unroll(0, "a", 1, 1))));
  std::atomic<bool> pushed{false};
  std::thread pusher([&] {
    EXPECT_TRUE(Accepted(q.Push(Unroll(0, "a", 1, 2))));
    pushed = true;
  });
  WaitForBlockedPusher(q);
  EXPECT_FALSE(pushed);
  int dropped = 0;
  EXPECT_EQ(q.Next(&dropped)->unroll.sequence(), 1);
  pusher.join();
  EXPECT_EQ(q.stats().pushers_waiting, 0);
  EXPECT_EQ(q.Next(&dropped)->unroll.sequence(), 2);
}

TEST_F(UnrollQueueTest, APusherThatWentAwayQueuesNothingAndItsStepsAreFreed) {
  UnrollQueue::Options o = Options();
  o.capacity = 1;
  o.synchronous = true;
  o.batch_steps = 16;
  UnrollQueue q(std::move(o));
  ASSERT_TRUE(Accepted(q.Push(Unroll(0, "a", 1, 1))));
  std::atomic<bool> gone{false};
  std::thread pusher([&] {
    EXPECT_EQ(q.Push(Unroll(0, "a", 1, 2), [&] { return gone.load(); }).status().code(), absl::StatusCode::kCancelled);
  });
  WaitForBlockedPusher(q);
  gone = true;
  pusher.join();  // Polled every second.
  int dropped = 0;
  ASSERT_TRUE(q.Next(&dropped).has_value());
  // Not a duplicate, and its steps no longer fill the version's batch.
  EXPECT_TRUE(Accepted(q.Push(Unroll(0, "a", 1, 2))));
  EXPECT_EQ(q.stats().received, 2);
}

TEST_F(UnrollQueueTest, CloseWakesWaitersWithTheReason) {
  UnrollQueue::Options o = Options();
  o.capacity = 1;
  UnrollQueue q(std::move(o));
  ASSERT_TRUE(Accepted(q.Push(Unroll(0, "a", 1, 1))));
  std::thread pusher([&] { EXPECT_EQ(q.Push(Unroll(0, "a", 1, 2)).status().code(), absl::StatusCode::kUnavailable); });
  WaitForBlockedPusher(q);
  q.Close(/*budget_done=*/false);
  pusher.join();
  int dropped = 0;
  EXPECT_FALSE(q.Next(&dropped).has_value());
  q.Close(/*budget_done=*/true);
  EXPECT_EQ(q.Push(Unroll(0, "b")).status().code(), absl::StatusCode::kOutOfRange);
}

TEST_F(UnrollQueueTest, ARestoredQueueKnowsWhatWasTrained) {
  UnrollQueue q(Options());
  ASSERT_TRUE(Accepted(q.Push(Unroll(0, "a", 1, 1))));
  ASSERT_TRUE(Accepted(q.Push(Unroll(0, "a", 1, 2))));
  q.MarkTrained({Unroll(0, "a", 1, 1)});
  UnrollQueue restored(Options());
  restored.Restore(3, q.Trained());
  EXPECT_EQ(RejectionOf(restored.Push(Unroll(3, "a", 1, 1))), v1::REJECTION_DUPLICATE);
  EXPECT_TRUE(Accepted(restored.Push(Unroll(3, "a", 1, 2))));  // Only queued before: lost, taken again.
  EXPECT_EQ(RejectionOf(restored.Push(Unroll(4, "a", 1, 3))), v1::REJECTION_AHEAD);
}

}  // namespace
}  // namespace imca::learner
