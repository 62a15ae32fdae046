// The actor: wires flags to an Actor.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <functional>
#include <optional>
#include <string>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/flags/usage.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "actor/actor.h"
#include "common/base/json.h"
#include "common/env/env.h"
#include "common/env/scenario_flags.h"
#include "common/protocol/unroll_check.h"
#include "common/rpc/grpc_util.h"
#include "common/rpc/metrics_flags.h"
#include "common/rpc/service_flags.h"
#include "common/rpc/transport.h"
#include "common/rpc/transport_flags.h"

ABSL_FLAG(std::string, learner, imca::kDefaultLearnerAddress, "learner address host:port");
ABSL_FLAG(std::string, reward_server, imca::kDefaultRewardServerAddress, "reward server address host:port");
namespace {
const imca::actor::ActorConfig kDefaults;  // Every default's one definition (with the scenario's tuning).
}  // namespace

ABSL_FLAG(std::string, algo, "",
          "the learner's algorithm, one of --list's algos, whose collection this actor takes (default: the first, "
          "mappo)");
ABSL_FLAG(std::optional<int>, envs, std::nullopt, "environments stepped together (default: the algorithm's; --list)");
ABSL_FLAG(std::optional<int>, unroll_length, std::nullopt, "steps per unroll (default: the scenario's; --list)");
ABSL_FLAG(int, eval_envs, kDefaults.eval_envs, "evaluation environments (same policy, not trained on)");
ABSL_FLAG(uint64_t, seed, kDefaults.seed,
          "seed of environments and action sampling (0: draw one from the clock and --actor_id)");
ABSL_FLAG(std::string, actor_id, "", "name reported to the learner (default: hostname:pid)");
ABSL_FLAG(int, rpc_timeout_ms, static_cast<int>(kDefaults.rpc_timeout.count()), "deadline of every RPC");
ABSL_FLAG(int, ack_timeout_ms, static_cast<int>(kDefaults.ack_timeout.count()),
          "longest wait for the learner's ack of one unroll; past it the stream is cancelled and the unroll resent");
ABSL_FLAG(int, score_delay_ms, 0,
          "testing: pause this long before each Score call, changing the order actors' calls arrive in");
ABSL_FLAG(int, sync_unrolls, kDefaults.sync_unrolls,
          "act this many unrolls with each policy version, then wait for the next version (0: asynchronous; "
          "-1: as the learner's policy asks, its batch_steps / actors env steps for a synchronous learner)");
ABSL_FLAG(std::string, trace_file, "",
          "if set, write env 0's newest finished training episode with its credit shares here (CSV)");

namespace {

// The training configuration as flag name: value (--print_config, and per
// scenario in --list); the per-process identity (id, seed, files) is left out.
std::string ConfigJson(const imca::actor::ActorConfig& c) {
  return imca::JsonObject()
      .Add("envs", c.num_envs)
      .Add("unroll_length", c.unroll_length)
      .Add("eval_envs", c.eval_envs)
      .Add("sync_unrolls", c.sync_unrolls)
      .Text();
}

// Each algorithm's defaults per scenario (DefaultActorConfig).
std::string DefaultsJson() {
  imca::JsonObject algos;
  for (const std::string& algo : imca::actor::ActorAlgoNames()) {
    imca::JsonObject scenarios;
    for (const std::string& scenario : imca::env::ScenarioNames()) {
      scenarios.Raw(scenario, ConfigJson(imca::actor::DefaultActorConfig(scenario, algo)));
    }
    algos.Raw(algo, scenarios.Text());
  }
  return algos.Text();
}

}  // namespace

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage("IMCA actor: steps environments and streams unrolls");
  absl::ParseCommandLine(argc, argv);
  using namespace imca;
  const absl::StatusOr<ServiceFlags> service_flags = ServiceFlagsFromFlags();
  if (!service_flags.ok()) {
    std::fprintf(stderr, "actor: %s\n", std::string(service_flags.status().message()).c_str());
    return 2;
  }
  if (service_flags->list) {
    std::printf("%s\n", JsonObject()
                            .Add("program", "actor")
                            .Add("scenarios", env::ScenarioNames())
                            .Add("default_scenario", env::ScenarioConfig{}.name)
                            .Add("max_unroll_transitions", kMaxTransitions)
                            .Add("max_door_timer", env::kMaxDoorTimer)
                            .Add("exit_refused", kExitRefused)
                            .Add("exit_misconfigured", kExitMisconfigured)
                            .Add("algos", actor::ActorAlgoNames())
                            .Raw("actor_defaults", DefaultsJson())
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

  const std::vector<std::string> algos = actor::ActorAlgoNames();
  const std::string algo = absl::GetFlag(FLAGS_algo).empty() ? algos.front() : absl::GetFlag(FLAGS_algo);
  if (std::find(algos.begin(), algos.end(), algo) == algos.end()) {
    return fail(absl::StrCat("--algo: '", algo, "' is not one of ", absl::StrJoin(algos, ", ")));
  }
  actor::ActorConfig config = actor::DefaultActorConfig((*scenario)->name(), algo);
  config.actor_id = id;
  if (const auto envs = absl::GetFlag(FLAGS_envs)) config.num_envs = *envs;
  if (const auto length = absl::GetFlag(FLAGS_unroll_length)) config.unroll_length = *length;
  config.eval_envs = absl::GetFlag(FLAGS_eval_envs);
  config.seed = absl::GetFlag(FLAGS_seed);
  config.sync_unrolls = absl::GetFlag(FLAGS_sync_unrolls);
  config.rpc_timeout = std::chrono::milliseconds(absl::GetFlag(FLAGS_rpc_timeout_ms));
  config.ack_timeout = std::chrono::milliseconds(absl::GetFlag(FLAGS_ack_timeout_ms));
  config.score_delay = std::chrono::milliseconds(absl::GetFlag(FLAGS_score_delay_ms));
  config.trace_file = absl::GetFlag(FLAGS_trace_file);
  config.status_file = service_flags->status_file;
  if (absl::Status valid = actor::Actor::Validate(config); !valid.ok()) return fail(std::string(valid.message()));
  if (service_flags->print_config) {
    std::printf("%s\n", ConfigJson(config).c_str());
    return 0;
  }
  if (config.seed == 0) {
    // The id (hostname:pid by default) tells replicas apart where every
    // container's pid is 1; the clock tells restarts apart.
    config.seed = static_cast<uint64_t>(std::chrono::system_clock::now().time_since_epoch().count()) ^
                  std::hash<std::string>{}(id);
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
  auto made = actor::Actor::Create(scenario->get(), config, *std::move(learner), *std::move(reward_server));
  if (!made.ok()) return fail(std::string(made.status().message()));
  actor::Actor& actor = **made;
  auto metrics_server = process_metrics.Serve(id.c_str(), {&actor.metrics()});
  if (!metrics_server.ok()) return fail(std::string(metrics_server.status().message()));
  const absl::Status status = actor.Run();
  if (IsRefusal(status)) {
    fail(std::string(status.message()));
    return kExitRefused;  // A supervisor must not restart it: the same credentials would be refused again.
  }
  if (absl::IsFailedPrecondition(status)) {
    fail(std::string(status.message()));
    return kExitMisconfigured;  // Restarted, it would meet the same learner.
  }
  if (!status.ok()) return fail(std::string(status.message()));
  std::fprintf(stderr, "%s: stopped after %lld unrolls\n", id.c_str(),
               static_cast<long long>(actor.unrolls_pushed()));
  return ShutdownRequested() ? service_flags->signal_exit_code : 0;
}
