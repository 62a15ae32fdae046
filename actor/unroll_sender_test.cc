// The UnrollSender with fake streams (narrow unit tests; actor_test runs it
// against a real learner service that fails on cue).
#include "actor/unroll_sender.h"

#include <memory>
#include <vector>

#include "gtest/gtest.h"

namespace imca::actor {
namespace {

// A stream that acks every unroll with `rejection` until write number
// `break_at` (0: never), which fails; Finish returns `finish`.
struct Script {
  v1::Rejection rejection = v1::REJECTION_NONE;
  int break_at = 0;
  grpc::Status finish = grpc::Status::OK;
};

class FakeStream final : public PushStream {
 public:
  FakeStream(Script script, std::vector<int64_t>* sequences) : script_(script), sequences_(sequences) {}
  void WaitForInitialMetadata() override {}
  bool WritesDone() override { return true; }
  grpc::Status Finish() override { return script_.finish; }
  bool NextMessageSize(uint32_t* size) override {
    *size = 1024;
    return true;
  }
  bool Read(v1::PushUnrollsResponse* ack) override {
    if (pending_ < 0) return false;
    ack->set_accepted(script_.rejection == v1::REJECTION_NONE);
    ack->set_rejection(script_.rejection);
    ack->set_policy_version(pending_);
    pending_ = -1;
    return true;
  }
  using grpc::internal::WriterInterface<v1::PushUnrollsRequest>::Write;
  bool Write(const v1::PushUnrollsRequest& request, grpc::WriteOptions) override {
    if (++writes_ == script_.break_at) return false;
    sequences_->push_back(request.unroll().sequence());
    pending_ = request.unroll().sequence();
    return true;
  }

 private:
  const Script script_;
  std::vector<int64_t>* sequences_;
  int writes_ = 0;
  int64_t pending_ = -1;
};

class UnrollSenderTest : public ::testing::Test {
 protected:
  // Streams opened in turn follow scripts_[0], scripts_[1], ... (the last
  // one repeats).
  StreamOpener Opener() {
    return [this](grpc::ClientContext*) {
      const Script& script = scripts_[std::min<size_t>(opened_, scripts_.size() - 1)];
      ++opened_;
      return std::make_unique<FakeStream>(script, &sequences_);
    };
  }
  v1::Unroll Unroll(int64_t sequence) {
    v1::Unroll u;
    u.set_sequence(sequence);
    u.set_actor_id("actor-3");
    return u;
  }

  std::vector<Script> scripts_{Script{}};
  size_t opened_ = 0;
  std::vector<int64_t> sequences_;
  StopSignal stop_;
  metrics::Registry registry_;
  metrics::Counter& reconnects_ =
      registry_.AddCounter({"imca_test_reconnects_total", metrics::Type::kCounter, "Reconnects."});
};

TEST_F(UnrollSenderTest, OpensAStreamPerBatchOfAcksAndGivesTheUnrollBack) {
  UnrollSenderOptions options;
  options.unrolls_per_stream = 2;
  UnrollSender sender(Opener(), options, &stop_);
  for (int64_t s = 1; s <= 5; ++s) {
    v1::Unroll u = Unroll(s);
    absl::StatusOr<v1::PushUnrollsResponse> ack = sender.Send(&u);
    ASSERT_TRUE(ack.ok()) << ack.status();
    EXPECT_TRUE(ack->accepted());
    EXPECT_EQ(ack->policy_version(), s);  // This unroll's ack.
    EXPECT_EQ(u.sequence(), s);           // Swapped back, not consumed.
    EXPECT_EQ(u.actor_id(), "actor-3");
  }
  EXPECT_EQ(opened_, 3u);  // 2 + 2 + 1.
  EXPECT_EQ(sequences_, (std::vector<int64_t>{1, 2, 3, 4, 5}));
}

TEST_F(UnrollSenderTest, PassesRejectionsToTheCaller) {
  scripts_ = {Script{v1::REJECTION_STALE}};
  UnrollSender sender(Opener(), UnrollSenderOptions{}, &stop_);
  v1::Unroll u = Unroll(1);
  absl::StatusOr<v1::PushUnrollsResponse> ack = sender.Send(&u);
  ASSERT_TRUE(ack.ok()) << ack.status();
  EXPECT_FALSE(ack->accepted());
  EXPECT_EQ(ack->rejection(), v1::REJECTION_STALE);
}

TEST_F(UnrollSenderTest, ABrokenStreamFailsTheSendAndTheNextOneReconnects) {
  // The first stream acks one unroll and breaks on the second write; the
  // learner ended it with UNAVAILABLE. The second stream works.
  scripts_ = {Script{v1::REJECTION_NONE, 2, grpc::Status(grpc::StatusCode::UNAVAILABLE, "learner restarting")},
              Script{}};
  UnrollSenderOptions options;
  options.reconnects = &reconnects_;
  UnrollSender sender(Opener(), options, &stop_);
  v1::Unroll first = Unroll(1), second = Unroll(2);
  ASSERT_TRUE(sender.Send(&first).ok());
  absl::StatusOr<v1::PushUnrollsResponse> failed = sender.Send(&second);
  EXPECT_EQ(failed.status().code(), absl::StatusCode::kUnavailable) << failed.status();
  EXPECT_EQ(second.sequence(), 2);  // Still in hand, to resend.
  EXPECT_EQ(reconnects_.value(), 0);
  ASSERT_TRUE(sender.Send(&second).ok());
  EXPECT_EQ(reconnects_.value(), 1);  // A new stream after one that had an ack.
  EXPECT_EQ(opened_, 2u);
}

TEST_F(UnrollSenderTest, AStreamClosedWithoutAnAckIsUnavailable) {
  scripts_ = {Script{v1::REJECTION_NONE, 1, grpc::Status::OK}};
  UnrollSenderOptions options;
  options.reconnects = &reconnects_;
  UnrollSender sender(Opener(), options, &stop_);
  v1::Unroll u = Unroll(1);
  absl::StatusOr<v1::PushUnrollsResponse> failed = sender.Send(&u);
  EXPECT_EQ(failed.status().code(), absl::StatusCode::kUnavailable);
  EXPECT_NE(failed.status().message().find("closed the stream"), std::string::npos);
  EXPECT_EQ(reconnects_.value(), 0);  // Never up: not a reconnect.
}

TEST_F(UnrollSenderTest, AfterStopNothingIsSent) {
  UnrollSender sender(Opener(), UnrollSenderOptions{}, &stop_);
  stop_.Stop();
  v1::Unroll u = Unroll(1);
  EXPECT_EQ(sender.Send(&u).status().code(), absl::StatusCode::kCancelled);
  EXPECT_EQ(opened_, 0u);
  EXPECT_EQ(u.sequence(), 1);
}

}  // namespace
}  // namespace imca::actor
