// The actor: wires flags to an Actor.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <functional>
#include <string>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/flags/usage.h"
#include "absl/strings/str_cat.h"
#include "actor/actor.h"
#include "common/env.h"
#include "common/grpc_util.h"
#include "common/json.h"
#include "common/metrics_flags.h"
#include "common/scenario_flags.h"
#include "common/transport.h"
#include "common/transport_flags.h"
#include "common/unroll_check.h"

ABSL_FLAG(std::string, learner, "127.0.0.1:50052", "learner address host:port");
ABSL_FLAG(std::string, reward_server, "127.0.0.1:50051", "reward server address host:port");
ABSL_FLAG(int, envs, imca::actor::ActorConfig{}.num_envs, "environments stepped together");
ABSL_FLAG(int, unroll_length, imca::actor::ActorConfig{}.unroll_length, "steps per unroll");
ABSL_FLAG(int, eval_envs, imca::actor::ActorConfig{}.eval_envs,
          "evaluation environments (same policy, not trained on)");
ABSL_FLAG(uint64_t, seed, 1, "seed of environments and action sampling (0: draw one from the clock and --actor_id)");
ABSL_FLAG(std::string, actor_id, "", "name reported to the learner (default: hostname:pid)");
ABSL_FLAG(int, rpc_timeout_ms, 10000, "deadline of every RPC");
ABSL_FLAG(int, ack_timeout_ms, 60000,
          "longest wait for the learner's ack of one unroll; past it the stream is cancelled and the unroll resent");
ABSL_FLAG(int, signal_exit_code, 0,
          "exit code when SIGINT/SIGTERM stops the actor before the learner is done (Kubernetes "
          "Jobs: 143, so that an evicted actor is replaced rather than counted as finished)");
ABSL_FLAG(int, sync_unrolls, 0,
          "synchronous collection (learner --synchronous): act this many unrolls with each policy "
          "version, then wait for the next version (0: asynchronous)");
ABSL_FLAG(bool, list, false,
          "print this binary's choices and limits (scenarios, the unroll cap, exit codes) as JSON and exit: what "
          "the Python tools ask instead of copying them");
ABSL_FLAG(std::string, status_file, "",
          "if set, write a one-line JSON progress record here every second (for a supervisor; docs/reliability.md)");
ABSL_FLAG(std::string, trace_file, "",
          "if set, write env 0's newest finished training episode with its credit shares here (CSV)");

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage("IMCA actor: steps environments and streams unrolls");
  absl::ParseCommandLine(argc, argv);
  using namespace imca;
  if (absl::GetFlag(FLAGS_list)) {
    std::printf("%s\n", JsonObject()
                            .Add("program", "actor")
                            .Add("scenarios", env::ScenarioNames())
                            .Add("max_unroll_transitions", kMaxTransitions)
                            .Add("max_door_timer", env::kMaxDoorTimer)
                            .Add("exit_refused", kExitRefused)
                            .Text()
                            .c_str());
    return 0;
  }
  std::string id = absl::GetFlag(FLAGS_actor_id);
  if (id.empty()) {
    char host[256] = {};
    gethostname(host, sizeof(host) - 1);
    id = absl::StrCat(host, ":", getpid());
  }
  auto fail = [&](const std::string& message) {
    std::fprintf(stderr, "%s: %s\n", id.c_str(), message.c_str());
    return 2;
  };

  auto scenario = ScenarioFromFlags();
  if (!scenario.ok()) return fail(std::string(scenario.status().message()));

  actor::ActorConfig config;
  config.actor_id = id;
  config.num_envs = absl::GetFlag(FLAGS_envs);
  config.unroll_length = absl::GetFlag(FLAGS_unroll_length);
  config.eval_envs = absl::GetFlag(FLAGS_eval_envs);
  config.seed = absl::GetFlag(FLAGS_seed);
  if (config.seed == 0) {
    // The id (hostname:pid by default) tells replicas apart where every
    // container's pid is 1; the clock tells restarts apart.
    config.seed = static_cast<uint64_t>(std::chrono::system_clock::now().time_since_epoch().count()) ^
                  std::hash<std::string>{}(id);
  }
  config.rpc_timeout = std::chrono::milliseconds(absl::GetFlag(FLAGS_rpc_timeout_ms));
  config.ack_timeout = std::chrono::milliseconds(absl::GetFlag(FLAGS_ack_timeout_ms));
  if (config.rpc_timeout.count() < 100 || config.ack_timeout.count() < 100) {
    return fail("--rpc_timeout_ms and --ack_timeout_ms must be >= 100");
  }
  config.trace_file = absl::GetFlag(FLAGS_trace_file);
  config.status_file = absl::GetFlag(FLAGS_status_file);
  const int signal_exit_code = absl::GetFlag(FLAGS_signal_exit_code);
  if (signal_exit_code < 0 || signal_exit_code > 255) return fail("--signal_exit_code must be in [0, 255]");
  if (config.num_envs < 1) return fail("--envs must be >= 1");
  if (config.unroll_length < 1) return fail("--unroll_length must be >= 1");
  if (config.eval_envs < 0) return fail("--eval_envs must be >= 0");
  config.sync_unrolls = absl::GetFlag(FLAGS_sync_unrolls);
  if (config.sync_unrolls < 0) return fail("--sync_unrolls must be >= 0");
  if (int64_t{config.num_envs} * config.unroll_length > kMaxTransitions) {
    return fail(absl::StrCat("--envs * --unroll_length must be <= ", kMaxTransitions));
  }

  absl::StatusOr<TransportConfig> transport = ClientTransportFromFlags();
  if (!transport.ok()) return fail(std::string(transport.status().message()));
  config.tls = transport->client_tls();
  ProcessMetrics process_metrics(RpcMetrics::Side::kClient,
                                 {v1::LearnerService::service_full_name(), v1::RewardService::service_full_name()});
  auto learner = MakeChannel(absl::GetFlag(FLAGS_learner), *transport, &process_metrics.rpc);
  if (!learner.ok()) return fail(std::string(learner.status().message()));
  auto reward_server = MakeChannel(absl::GetFlag(FLAGS_reward_server), *transport, &process_metrics.rpc);
  if (!reward_server.ok()) return fail(std::string(reward_server.status().message()));

  InstallShutdownSignalHandlers();
  std::fprintf(stderr, "%s: dialling the learner at %s and the reward server at %s (%s)\n", id.c_str(),
               absl::GetFlag(FLAGS_learner).c_str(), absl::GetFlag(FLAGS_reward_server).c_str(),
               TransportSummary(*transport, /*server=*/false).c_str());
  actor::Actor actor(scenario->get(), config, *std::move(learner), *std::move(reward_server));
  auto metrics_server = process_metrics.Serve(id.c_str(), {&actor.metrics()});
  if (!metrics_server.ok()) return fail(std::string(metrics_server.status().message()));
  const absl::Status status = actor.Run();
  if (IsRefusal(status)) {
    fail(std::string(status.message()));
    return kExitRefused;  // A supervisor must not restart it: the same credentials would be refused again.
  }
  if (!status.ok()) return fail(std::string(status.message()));
  std::fprintf(stderr, "%s: stopped after %lld unrolls\n", id.c_str(),
               static_cast<long long>(actor.unrolls_pushed()));
  return ShutdownRequested() ? signal_exit_code : 0;
}
