// The learner: wires flags to a Learner and serves LearnerService.
#include <cstdio>
#include <optional>
#include <thread>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/flags/usage.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "common/base/json.h"
#include "common/base/settings.h"
#include "common/env/env.h"
#include "common/env/scenario_flags.h"
#include "common/nn/blas_kernels.h"
#include "common/protocol/unroll_check.h"
#include "common/rpc/grpc_util.h"
#include "common/rpc/metrics_flags.h"
#include "common/rpc/service_flags.h"
#include "common/rpc/transport_flags.h"
#include "learner/algorithms/registry.h"
#include "learner/learner.h"
#include "learner/learner_flags.h"
#include "learner/learner_service.h"

ABSL_FLAG(std::string, run_dir, "", "run folder for metrics.csv and checkpoints/");
ABSL_FLAG(std::string, resume, "", "checkpoint directory to resume from");
ABSL_FLAG(bool, auto_resume, false,
          "resume from <run_dir>/checkpoints if it holds a checkpoint, else start fresh "
          "(for restarts under docker-compose or Kubernetes)");
ABSL_FLAG(int, max_streams, imca::learner::LearnerServiceImpl::kDefaultMaxStreams,
          "unroll streams served at once (one per actor), and as many GetPolicy calls waiting for a new "
          "version; more end with RESOURCE_EXHAUSTED and retry");
ABSL_FLAG(double, linger_seconds, 2,
          "after the budget, keep serving this long so that actors in backoff learn it is done");
ABSL_FLAG(std::string, trained_log, "",
          "if set, append a CSV row per trained unroll (iteration, actor_id, incarnation, sequence, policy_version)");

namespace {

// What the shared settings default to (LearnerConfig's).
const imca::learner::LearnerConfig kDefaults;

int Fail(const std::string& message) {
  std::fprintf(stderr, "learner: %s\n", message.c_str());
  return 2;
}

// Each algorithm's defaults per scenario (DefaultLearnerConfig).
std::string DefaultsJson() {
  using namespace imca;
  JsonObject algos;
  for (const std::string& name : learner::Algorithms().Names()) {
    JsonObject scenarios;
    for (const std::string& scenario : env::ScenarioNames()) {
      scenarios.Raw(scenario, learner::LearnerConfigJson(*learner::DefaultLearnerConfig(scenario, name)));
    }
    algos.Raw(name, scenarios.Text());
  }
  return algos.Text();
}

// --list: one JSON object.
std::string ListJson() {
  using namespace imca;
  std::string columns;
  for (const learner::Column& c : learner::IterationColumns()) {
    absl::StrAppend(&columns, columns.empty() ? "" : ", ",
                    JsonObject()
                        .Add("name", c.name)
                        .Add("help", c.help)
                        .Raw("prometheus", c.family != nullptr ? JsonString(c.family) : "null")
                        .Raw("algorithm", !c.algorithm.empty() ? JsonString(c.algorithm) : "null")
                        .Add("wall_clock", c.wall_clock)
                        .Text());
  }
  return JsonObject()
             .Add("program", "learner")
             .Add("scenarios", env::ScenarioNames())
             .Add("algos", learner::Algorithms().Names())
             .Add("default_algo", learner::Algorithms().entries().front().name)
             .Add("success_window", kDefaults.metrics_window)
             .Add("max_actor_ids", kDefaults.max_actor_ids)
             .Add("max_unroll_transitions", kMaxTransitions)
             .Add("exit_refused", kExitRefused)
             .Add("exit_misconfigured", kExitMisconfigured)
             .Raw("learner_settings", SettingRowsJson(learner::LearnerSettingRows()))
             .Raw("learner_defaults", DefaultsJson())
             .Raw("metrics_columns", absl::StrCat("[", columns, "]"))
             .Text() +
         "\n";
}

// Writes the learner's status record (--status_file, read by a supervisor)
// if `path` is set; a failure is reported, not fatal.
void WriteLearnerStatus(const std::string& path, const imca::learner::Learner& learner) {
  if (path.empty()) return;  // Status() takes the learner's locks.
  const absl::Status written = imca::WriteStatusFile(path, learner.Status());
  if (!written.ok()) std::fprintf(stderr, "learner: status: %s\n", std::string(written.message()).c_str());
}

// Runs the learner's training to its end while its server answers: a
// watcher turns a shutdown signal (which only sets a flag) into Stop() and
// writes the status file every second, from its own thread, so that a
// wedged training thread shows as a growing seconds_stalled, not a silent
// file. After the budget it keeps answering up to `linger_seconds`, so that
// actors learn that it is done (OUT_OF_RANGE on push, done in GetStatus)
// instead of retrying. Returns Run()'s status.
absl::Status TrainWhileServing(imca::learner::Learner* learner, const std::string& status_file,
                               double linger_seconds) {
  using imca::ShutdownRequested;
  std::atomic<bool> finished{false};
  std::thread watcher([&] {
    auto last_status = std::chrono::steady_clock::time_point{};
    while (!finished.load() && !ShutdownRequested()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      if (std::chrono::steady_clock::now() - last_status > std::chrono::seconds(1)) {
        last_status = std::chrono::steady_clock::now();
        WriteLearnerStatus(status_file, *learner);
      }
    }
    learner->Stop();
  });
  const absl::Status run = learner->Run();
  finished.store(true);
  watcher.join();
  const auto linger_end = std::chrono::steady_clock::now() + std::chrono::duration<double>(linger_seconds);
  while (run.ok() && learner->Status().done() && !ShutdownRequested() &&
         std::chrono::steady_clock::now() < linger_end) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return run;
}

}  // namespace

int main(int argc, char** argv) {
  imca::nn::UseTheCpusBlasKernels(argv);  // First: it may re-execute the binary.
  using namespace imca;
  absl::SetProgramUsageMessage(absl::StrCat("IMCA learner: trains the agents with ",
                                            absl::StrJoin(learner::Algorithms().Names(), ", "),
                                            " (--algo) and serves the policy over gRPC"));
  ParseCommandLineWithSettings(argc, argv, learner::LearnerSettingRows());
  const absl::StatusOr<ServiceFlags> service_flags = ServiceFlagsFromFlags();
  if (!service_flags.ok()) return Fail(std::string(service_flags.status().message()));
  if (service_flags->list) {
    std::fputs(ListJson().c_str(), stdout);
    return 0;
  }

  if (absl::GetFlag(FLAGS_linger_seconds) < 0) return Fail("--linger_seconds must be >= 0");
  auto scenario = ScenarioFromFlags();
  if (!scenario.ok()) return Fail(std::string(scenario.status().message()));

  absl::StatusOr<learner::LearnerConfig> resolved = learner::LearnerConfigFromFlags((*scenario)->name());
  if (!resolved.ok()) return Fail(std::string(resolved.status().message()));
  learner::LearnerConfig config = *std::move(resolved);
  config.run_dir = absl::GetFlag(FLAGS_run_dir);
  config.trained_log = absl::GetFlag(FLAGS_trained_log);
  if (service_flags->print_config) {
    // Validated as a start would be, without a run folder to create.
    learner::LearnerConfig check = config;
    check.run_dir.clear();
    check.trained_log.clear();
    auto checked = learner::Learner::Create(scenario->get(), check);
    if (!checked.ok()) return Fail(std::string(checked.status().message()));
    std::printf("%s\n", learner::LearnerConfigJson(config).c_str());
    return 0;
  }
  absl::StatusOr<ServerOptions> server_options = ServerOptionsFromFlags();
  if (!server_options.ok()) return Fail(std::string(server_options.status().message()));
  const int max_streams = absl::GetFlag(FLAGS_max_streams);
  if (max_streams < 1) return Fail("--max_streams must be >= 1");
  auto learner = learner::Learner::Create(scenario->get(), config);
  if (!learner.ok()) return Fail(std::string(learner.status().message()));
  const absl::StatusOr<std::string> resume =
      learner::ResumeFolder(absl::GetFlag(FLAGS_resume), absl::GetFlag(FLAGS_auto_resume), config.run_dir);
  if (!resume.ok()) return Fail(std::string(resume.status().message()));
  if (!resume->empty()) {
    if (absl::Status restored = (*learner)->Restore(*resume); !restored.ok()) {
      return Fail(absl::StrCat("--resume: ", restored.message()));
    }
    std::fprintf(stderr, "learner: resumed at policy version %lld\n",
                 static_cast<long long>((*learner)->Status().policy_version()));
  }

  learner::LearnerServiceImpl service(learner->get(), max_streams);
  ProcessMetrics process_metrics(RpcMetrics::Side::kServer, {v1::LearnerService::service_full_name()});
  server_options->rpc_metrics = &process_metrics.rpc;
  auto metrics_server = process_metrics.Serve("learner", {&(*learner)->metrics(), &service.metrics()});
  if (!metrics_server.ok()) return Fail(std::string(metrics_server.status().message()));
  InstallShutdownSignalHandlers();
  int port = 0;
  auto server = ServeFromFlags(kDefaultLearnerAddress, {&service}, *server_options, &port);
  if (!server.ok()) return Fail(std::string(server.status().message()));
  std::fprintf(stderr, "learner: serving on port %d (%s)\n", port,
               TransportSummary(server_options->transport, /*server=*/true).c_str());

  const std::string& status_file = service_flags->status_file;
  const absl::Status run = TrainWhileServing(learner->get(), status_file, absl::GetFlag(FLAGS_linger_seconds));
  (*server)->Shutdown(DeadlineIn(std::chrono::seconds(3)));
  WriteLearnerStatus(status_file, **learner);
  if (!run.ok()) return Fail(absl::StrCat("training failed: ", run.message()));
  const v1::LearnerStatus status = (*learner)->Status();
  std::fprintf(stderr, "learner: stopped at %lld env steps, policy version %lld\n",
               static_cast<long long>(status.env_steps()),
               static_cast<long long>(status.policy_version()));
  return status.done() ? 0 : service_flags->signal_exit_code;
}
