#include "common/rpc/service_flags.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "absl/flags/declare.h"
#include "absl/flags/flag.h"
#include "common/base/atomic_file.h"
#include "gmock/gmock.h"
#include "google/protobuf/util/json_util.h"
#include "google/protobuf/util/message_differencer.h"
#include "gtest/gtest.h"
#include "imca/v1/learner_service.pb.h"

ABSL_DECLARE_FLAG(int, signal_exit_code);
ABSL_DECLARE_FLAG(std::string, status_file);

namespace imca {
namespace {

using ::testing::HasSubstr;
using ::testing::StartsWith;

TEST(ServiceFlagsTest, SignalExitCodeIsAnExitCode) {
  absl::SetFlag(&FLAGS_status_file, "/tmp/x.status.json");
  absl::SetFlag(&FLAGS_signal_exit_code, 143);
  absl::StatusOr<ServiceFlags> flags = ServiceFlagsFromFlags();
  ASSERT_TRUE(flags.ok()) << flags.status();
  EXPECT_EQ(flags->signal_exit_code, 143);
  EXPECT_EQ(flags->status_file, "/tmp/x.status.json");
  absl::SetFlag(&FLAGS_signal_exit_code, 256);
  flags = ServiceFlagsFromFlags();
  EXPECT_EQ(flags.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(flags.status().message(), HasSubstr("--signal_exit_code"));
  absl::SetFlag(&FLAGS_signal_exit_code, 0);
  absl::SetFlag(&FLAGS_status_file, "");
}

TEST(ServiceFlagsTest, StatusFilesAreTheProtoInItsJsonMappingWithTheTime) {
  const std::string path = ::testing::TempDir() + "/status_" + std::to_string(getpid()) + ".json";
  v1::ActorStatus status;
  status.set_actor_id("actor-1");
  status.set_incarnation(0xfedcba9876543210ULL);
  status.set_unrolls_pushed(12);
  status.set_state(v1::ActorStatus::ACTING);
  const double before = UnixSeconds();
  ASSERT_TRUE(WriteStatusFile(path, status).ok());
  std::ifstream in(path);
  std::string line;
  ASSERT_TRUE(std::getline(in, line));
  EXPECT_FALSE(std::getline(in, line)) << "one line";
  std::ifstream again(path);
  std::getline(again, line);
  // The proto's names, every field (unrolls_resent at its default too, the
  // empty map as {}), 64-bit integers as numbers, then the time.
  EXPECT_THAT(line, StartsWith(R"({"actor_id":"actor-1","incarnation":18364758544493064720,)"
                               R"("unrolls_pushed":12,"unrolls_resent":0,"transitions_scored":0,)"
                               R"("state":"ACTING","phase_seconds":{},"time":)"));
  const double time = std::stod(line.substr(line.rfind(':') + 1));
  EXPECT_GE(time, before - 0.001);
  EXPECT_LE(time, UnixSeconds() + 0.001);
  // It parses back into the same message (the time is not one of its
  // fields; the mapping's parser takes 64-bit integers as numbers too).
  google::protobuf::util::JsonParseOptions options;
  options.ignore_unknown_fields = true;
  v1::ActorStatus parsed;
  ASSERT_TRUE(google::protobuf::util::JsonStringToMessage(line, &parsed, options).ok());
  EXPECT_TRUE(google::protobuf::util::MessageDifferencer::Equals(parsed, status));
  std::filesystem::remove(path);
}

TEST(ServiceFlagsTest, OnlyTheSixtyFourBitFieldsAreUnquoted) {
  const std::string path = ::testing::TempDir() + "/status_ids_" + std::to_string(getpid()) + ".json";
  v1::ActorStatus status;
  status.set_actor_id("7");  // A string that looks like a number stays a string.
  status.set_unrolls_pushed(-1);
  status.set_unrolls_resent(7);
  ASSERT_TRUE(WriteStatusFile(path, status).ok());
  std::ifstream in(path);
  std::string line;
  ASSERT_TRUE(std::getline(in, line));
  EXPECT_THAT(line, StartsWith(R"({"actor_id":"7","incarnation":0,"unrolls_pushed":-1,"unrolls_resent":7,)"));
  v1::LearnerStatus learner;
  learner.add_actors_seen("1");
  learner.set_env_steps(int64_t{1} << 40);
  learner.set_queue_depth(3);
  ASSERT_TRUE(WriteStatusFile(path, learner).ok());
  std::ifstream again(path);
  ASSERT_TRUE(std::getline(again, line));
  EXPECT_THAT(line, HasSubstr(R"("env_steps":1099511627776,)"));
  EXPECT_THAT(line, HasSubstr(R"("actors_seen":["1"],)"));
  EXPECT_THAT(line, HasSubstr(R"("queue_depth":3,)"));
  std::filesystem::remove(path);
}

TEST(ServiceFlagsTest, NoPathWritesNothingAndAnUnwritablePathIsAnError) {
  EXPECT_TRUE(WriteStatusFile("", v1::LearnerStatus()).ok());
  const absl::Status failed = WriteStatusFile("/nonexistent-dir/x/status.json", v1::LearnerStatus());
  EXPECT_FALSE(failed.ok());
}

}  // namespace
}  // namespace imca
