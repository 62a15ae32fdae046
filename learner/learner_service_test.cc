// The PushUnrolls loop through its seam (PushUnrollsInternal) with a scripted
// stream, no network: one ack per unroll, in order, typed by the learner's
// answer; the stream ends when the client stops reading acks.
#include "learner/learner_service.h"
#include "learner/push_testing.h"

#include <deque>
#include <string>
#include <vector>

#include "common/env/env.h"
#include "common/protocol/test_unrolls.h"
#include "gtest/gtest.h"

namespace imca::learner {
namespace {

// Hands out `requests` in order, records the acks, and fails the write of
// ack number `fail_write` (0: none).
class ScriptedStream final : public LearnerServiceImpl::PushStream {
 public:
  ScriptedStream(std::vector<v1::Unroll> unrolls, int fail_write) : fail_write_(fail_write) {
    for (v1::Unroll& u : unrolls) *requests_.emplace_back().mutable_unroll() = std::move(u);
  }
  void SendInitialMetadata() override {}
  bool NextMessageSize(uint32_t* size) override {
    *size = 64 << 20;
    return !requests_.empty();
  }
  bool Read(v1::PushUnrollsRequest* request) override {
    if (requests_.empty()) return false;
    *request = std::move(requests_.front());
    requests_.pop_front();
    return true;
  }
  using grpc::internal::WriterInterface<v1::PushUnrollsResponse>::Write;
  bool Write(const v1::PushUnrollsResponse& ack, grpc::WriteOptions) override {
    if (static_cast<int>(acks.size()) + 1 == fail_write_) return false;
    acks.push_back(ack);
    return true;
  }

  std::vector<v1::PushUnrollsResponse> acks;
  size_t unread() const { return requests_.size(); }

 private:
  std::deque<v1::PushUnrollsRequest> requests_;
  const int fail_write_;
};

class LearnerServiceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    auto scenario = env::MakeScenario(env::ScenarioConfig{}, env::DefaultMapDir());
    ASSERT_TRUE(scenario.ok());
    scenario_ = *std::move(scenario);
    config_.batch_steps = 1 << 20;  // Never trains: admission only.
    config_.synchronous = false;
    config_.checkpoint_every = 0;
    config_.checkpoint_seconds = 0;
  }
  v1::Unroll Unroll(int64_t version, int64_t sequence) {
    v1::Unroll u = testing::RandomUnroll(*scenario_, 8, 4, static_cast<uint64_t>(sequence));
    u.set_policy_version(version);
    u.set_actor_id("actor-7");
    u.set_incarnation(42);
    u.set_sequence(sequence);
    return u;
  }
  std::unique_ptr<env::Scenario> scenario_;
  LearnerConfig config_;
};

TEST_F(LearnerServiceTest, AcksEachUnrollInOrderWithItsRejection) {
  auto learner = Learner::Create(scenario_.get(), config_);
  ASSERT_TRUE(learner.ok()) << learner.status();
  LearnerServiceImpl service(learner->get());
  v1::Unroll invalid = Unroll(0, 3);
  invalid.clear_actions();
  ScriptedStream stream({Unroll(0, 1), Unroll(0, 1), invalid, Unroll(5, 4), Unroll(0, 2)}, /*fail_write=*/0);
  grpc::ServerContext context;
  EXPECT_TRUE(service.PushUnrollsInternal(&context, &stream).ok());
  ASSERT_EQ(stream.acks.size(), 5u);
  EXPECT_TRUE(stream.acks[0].accepted());
  EXPECT_EQ(stream.acks[1].rejection(), v1::REJECTION_DUPLICATE);  // The same incarnation and sequence.
  EXPECT_EQ(stream.acks[2].rejection(), v1::REJECTION_INVALID);
  EXPECT_NE(stream.acks[2].error().find("unroll.actions"), std::string::npos) << stream.acks[2].error();
  EXPECT_EQ(stream.acks[3].rejection(), v1::REJECTION_AHEAD);  // Version 5 of a learner at 0.
  EXPECT_TRUE(stream.acks[4].accepted());
  for (const v1::PushUnrollsResponse& ack : stream.acks) EXPECT_EQ(ack.policy_version(), 0);
  EXPECT_EQ((*learner)->Status().unrolls_received(), 2);
}

TEST_F(LearnerServiceTest, StopsReadingWhenAnAckCannotBeWritten) {
  auto learner = Learner::Create(scenario_.get(), config_);
  ASSERT_TRUE(learner.ok()) << learner.status();
  LearnerServiceImpl service(learner->get());
  ScriptedStream stream({Unroll(0, 1), Unroll(0, 2), Unroll(0, 3)}, /*fail_write=*/2);
  grpc::ServerContext context;
  EXPECT_TRUE(service.PushUnrollsInternal(&context, &stream).ok());
  // The second unroll was taken, its ack lost: the actor resends it and the
  // learner answers DUPLICATE. The third was never read.
  EXPECT_EQ(stream.acks.size(), 1u);
  EXPECT_EQ(stream.unread(), 1u);
  EXPECT_EQ((*learner)->Status().unrolls_received(), 2);
}

TEST_F(LearnerServiceTest, EndsTheStreamOnceTheBudgetIsDone) {
  config_.budget_steps = 8 * 4;  // One unroll.
  config_.batch_steps = 8 * 4;
  auto learner = Learner::Create(scenario_.get(), config_);
  ASSERT_TRUE(learner.ok()) << learner.status();
  LearnerServiceImpl service(learner->get());
  ASSERT_TRUE(Accepted((*learner)->Push(Unroll(0, 1))));
  ASSERT_TRUE((*learner)->Run().ok());  // Trains the one unroll: done.
  ScriptedStream stream({Unroll(1, 2)}, /*fail_write=*/0);
  grpc::ServerContext context;
  const grpc::Status status = service.PushUnrollsInternal(&context, &stream);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::OUT_OF_RANGE) << status.error_message();
  EXPECT_TRUE(stream.acks.empty());
}

}  // namespace
}  // namespace imca::learner
