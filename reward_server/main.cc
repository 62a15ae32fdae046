// The reward server: wires flags to a Scorer and serves RewardService.
#include <chrono>
#include <cstdio>
#include <optional>
#include <fstream>
#include <thread>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/flags/usage.h"
#include "absl/strings/str_cat.h"
#include "common/base/json.h"
#include "common/base/settings.h"
#include "common/env/env.h"
#include "common/env/scenario_flags.h"
#include "common/nn/blas_kernels.h"
#include "common/rpc/grpc_util.h"
#include "common/rpc/metrics_flags.h"
#include "common/rpc/service_flags.h"
#include "common/rpc/transport_flags.h"
#include "reward_server/credit/registry.h"
#include "reward_server/make_scorer.h"
#include "reward_server/reward_flags.h"
#include "reward_server/reward_service.h"

namespace {
const imca::reward::ServiceLimits kLimits;
}  // namespace

ABSL_FLAG(std::string, snapshot, "",
          "snapshot file: restored at start (count kinds: with the journal of every increment since, "
          "<snapshot>.journal-*), written periodically and at shutdown");
ABSL_FLAG(int, snapshot_every, 30,
          "seconds between periodic snapshots (0: only at shutdown); bounds what a kill loses of rnd and sf "
          "models, and how much journal a count kind replays");
ABSL_FLAG(bool, journal_fsync, false,
          "count kinds: fdatasync the journal before each Score answer (survives a machine crash, not only a "
          "killed process; docs/reliability.md)");
ABSL_FLAG(int, max_inflight, kLimits.max_inflight,
          "Score calls served at once; more end with RESOURCE_EXHAUSTED (the actor retries)");
ABSL_FLAG(int, max_inflight_per_actor, kLimits.max_inflight_per_actor,
          "Score calls of one actor id served at once, so that one flooding client cannot starve the rest");

namespace {

int Fail(const std::string& message) {
  std::fprintf(stderr, "reward_server: %s\n", message.c_str());
  return 2;
}

// The configuration as flag name: value (--print_config, and per reward
// kind in --list); passed back as flags it resolves the same.
std::string ConfigJson(const imca::reward::RewardConfig& config) {
  using namespace imca;
  JsonObject json;
  reward::AddRewardConfigJson(config, &json);
  json.Add("snapshot_every", absl::GetFlag(FLAGS_snapshot_every)).Add("journal_fsync", absl::GetFlag(FLAGS_journal_fsync));
  return json.Text();
}

// --list: one JSON object (reward_defaults by kind, then scenario). Each
// reward kind is built on `scenario` to ask which credit modes it serves; a
// kind that cannot be built is an error.
int List(const imca::env::Scenario& scenario) {
  using namespace imca;
  JsonObject rewards, defaults;
  for (const std::string& kind : reward::RewardKinds()) {
    JsonObject by_scenario;
    for (const std::string& name : env::ScenarioNames()) {
      by_scenario.Raw(name, ConfigJson(reward::DefaultRewardConfig(kind, name)));
    }
    defaults.Raw(kind, by_scenario.Text());
    auto novelty = reward::MakeNovelty(kind, scenario, reward::ScorerConfig{});
    if (!novelty.ok()) return Fail(absl::StrCat("--list: reward kind ", kind, ": ", novelty.status().message()));
    rewards.Add(kind, reward::ServedCredits(**novelty));
  }
  std::printf("%s\n", JsonObject()
                          .Add("program", "reward_server")
                          .Add("scenarios", env::ScenarioNames())
                          .Raw("rewards", rewards.Text())
                          .Add("default_reward", reward::RewardKinds().front())
                          .Add("credits", reward::CreditRules().Names())
                          .Add("permutations", reward::PermutationNames())
                          .Raw("reward_settings", SettingRowsJson(reward::RewardSettingRows()))
                          .Raw("reward_defaults", defaults.Text())
                          .Text()
                          .c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  imca::nn::UseTheCpusBlasKernels(argv);  // First: it may re-execute the binary.
  using namespace imca;
  absl::SetProgramUsageMessage("IMCA reward server: per-agent credited intrinsic rewards over gRPC");
  ParseCommandLineWithSettings(argc, argv, reward::RewardSettingRows());
  const absl::StatusOr<ServiceFlags> service_flags = ServiceFlagsFromFlags();
  if (!service_flags.ok()) return Fail(std::string(service_flags.status().message()));

  auto scenario = ScenarioFromFlags();
  if (!scenario.ok()) return Fail(std::string(scenario.status().message()));
  if (service_flags->list) return List(**scenario);
  absl::StatusOr<ServerOptions> server_options = ServerOptionsFromFlags();
  if (!server_options.ok()) return Fail(std::string(server_options.status().message()));

  absl::StatusOr<reward::RewardConfig> resolved = reward::RewardConfigFromFlags((*scenario)->name());
  if (!resolved.ok()) return Fail(std::string(resolved.status().message()));
  const std::string& kind = resolved->kind;
  const reward::ScorerConfig& config = resolved->scorer;
  auto made = reward::MakeScorer(kind, **scenario, config, resolved->options);
  if (!made.ok()) return Fail(absl::StrCat("--reward ", kind, ": ", made.status().message()));
  if (absl::GetFlag(FLAGS_snapshot_every) < 0) return Fail("--snapshot_every must be >= 0");
  if (service_flags->print_config) {
    std::printf("%s\n", ConfigJson(*resolved).c_str());
    return 0;
  }
  std::unique_ptr<reward::Scorer> scorer = *std::move(made);

  const std::string snapshot = absl::GetFlag(FLAGS_snapshot);
  if (!snapshot.empty()) {
    const bool resumed = std::ifstream(snapshot).good();
    if (absl::Status restored = scorer->Restore(snapshot, absl::GetFlag(FLAGS_journal_fsync)); !restored.ok()) {
      return Fail(absl::StrCat("--snapshot: ", restored.message()));
    }
    const std::optional<int64_t> transitions = scorer->DurableTransitions();
    if (resumed || transitions.value_or(0) > 0) {
      std::fprintf(stderr, "reward_server: restored from %s (%lld transitions counted)\n", snapshot.c_str(),
                   static_cast<long long>(transitions.value_or(-1)));
    }
  }

  reward::ServiceLimits limits;
  limits.max_inflight = absl::GetFlag(FLAGS_max_inflight);
  limits.max_inflight_per_actor = absl::GetFlag(FLAGS_max_inflight_per_actor);
  if (limits.max_inflight < 1) return Fail("--max_inflight must be >= 1");
  if (limits.max_inflight_per_actor < 1) return Fail("--max_inflight_per_actor must be >= 1");
  reward::RewardServiceImpl service(scenario->get(), scorer.get(), kind, config, snapshot, limits);
  ProcessMetrics process_metrics(RpcMetrics::Side::kServer, {v1::RewardService::service_full_name()});
  server_options->rpc_metrics = &process_metrics.rpc;
  auto metrics_server = process_metrics.Serve("reward_server", {&service.metrics()});
  if (!metrics_server.ok()) return Fail(std::string(metrics_server.status().message()));
  InstallShutdownSignalHandlers();
  int port = 0;
  auto server = ServeFromFlags(kDefaultRewardServerAddress, {&service}, *server_options, &port);
  if (!server.ok()) return Fail(std::string(server.status().message()));
  std::fprintf(stderr, "reward_server: serving %s/%s credit=%s on port %d (%s)\n",
               std::string((*scenario)->name()).c_str(), kind.c_str(), config.credit.c_str(), port,
               TransportSummary(server_options->transport, /*server=*/true).c_str());

  const auto period = std::chrono::seconds(absl::GetFlag(FLAGS_snapshot_every));
  auto write_status = [&] {
    if (service_flags->status_file.empty()) return;  // Stats() takes the scorer's lock.
    const absl::Status written = WriteStatusFile(service_flags->status_file, service.Stats());
    if (!written.ok()) std::fprintf(stderr, "reward_server: status: %s\n", std::string(written.message()).c_str());
  };
  auto last_snapshot = std::chrono::steady_clock::now();
  auto last_status = std::chrono::steady_clock::time_point{};
  while (!ShutdownRequested()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    if (std::chrono::steady_clock::now() - last_status > std::chrono::seconds(1)) {
      last_status = std::chrono::steady_clock::now();
      write_status();
    }
    if (!snapshot.empty() && period.count() > 0 &&
        std::chrono::steady_clock::now() - last_snapshot > period) {
      if (absl::Status saved = scorer->Save(snapshot); !saved.ok()) {
        std::fprintf(stderr, "reward_server: snapshot failed: %s\n", std::string(saved.message()).c_str());
      }
      last_snapshot = std::chrono::steady_clock::now();
    }
  }
  service.StopAccepting();
  (*server)->Shutdown(DeadlineIn(std::chrono::seconds(5)));
  if (!snapshot.empty()) {
    if (absl::Status saved = scorer->Save(snapshot); !saved.ok()) {
      return Fail(absl::StrCat("final snapshot failed: ", saved.message()));
    }
  }
  write_status();
  std::fprintf(stderr, "reward_server: stopped\n");
  return service_flags->signal_exit_code;
}
