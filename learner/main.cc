// The learner: wires flags to a Learner and serves LearnerService.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <thread>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/flags/usage.h"
#include "absl/strings/str_cat.h"
#include "common/env.h"
#include "common/grpc_util.h"
#include "common/scenario_flags.h"
#include "learner/learner.h"
#include "learner/learner_service.h"

ABSL_FLAG(std::string, listen, "127.0.0.1:50052", "host:port to serve on (port 0: any free port)");
ABSL_FLAG(std::string, port_file, "", "if set, write the bound port to this file once serving");
ABSL_FLAG(std::string, run_dir, "", "run folder for metrics.csv and checkpoints/");
ABSL_FLAG(std::string, resume, "", "checkpoint directory to resume from");
ABSL_FLAG(bool, auto_resume, false,
          "resume from <run_dir>/checkpoints if it holds a checkpoint, else start fresh "
          "(for restarts under docker-compose or Kubernetes)");
ABSL_FLAG(int64_t, steps, 2000000, "budget in joint env steps (0: until stopped)");
ABSL_FLAG(int64_t, batch_steps, 4096, "joint env steps per PPO iteration");
ABSL_FLAG(int, epochs, 4, "PPO epochs per iteration");
ABSL_FLAG(int, minibatches, 4, "PPO minibatches per epoch");
ABSL_FLAG(double, lr, 5e-4, "Adam learning rate");
ABSL_FLAG(double, entropy_coef, 0.01, "entropy bonus coefficient");
ABSL_FLAG(double, clip, 0.2, "PPO ratio clip");
ABSL_FLAG(double, gamma, 0.99, "extrinsic discount");
ABSL_FLAG(double, gamma_int, 0.99, "intrinsic discount");
ABSL_FLAG(double, lambda, 0.95, "GAE lambda");
ABSL_FLAG(double, intrinsic_coef, 1.0, "c_int: weight of the intrinsic advantage");
ABSL_FLAG(int, hidden, 64, "hidden layer width");
ABSL_FLAG(int, max_policy_lag, 4, "drop unrolls older than this many policy versions");
ABSL_FLAG(int, queue_capacity, 4, "unrolls waiting for training before PushUnrolls blocks the actors");
ABSL_FLAG(int, checkpoint_every, 50, "iterations between checkpoints");
ABSL_FLAG(uint64_t, seed, 1, "seed of network initialisation and minibatch shuffling");
ABSL_FLAG(int, threads, 1, "LibTorch intra-op threads");
ABSL_FLAG(int64_t, max_batch_mb, 8192,
          "cap on an iteration's feature arrays in MB (batch_steps and unroll sizes over it are rejected)");
ABSL_FLAG(double, linger_seconds, 2,
          "after the budget, keep serving this long so that actors in backoff learn it is done");
ABSL_FLAG(int, signal_exit_code, 0,
          "exit code when SIGINT/SIGTERM stops training before the budget (Kubernetes Jobs: 143, "
          "so that an evicted learner is replaced rather than counted as finished)");

namespace {

int Fail(const std::string& message) {
  std::fprintf(stderr, "learner: %s\n", message.c_str());
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage("IMCA learner: multi-agent PPO over gRPC");
  absl::ParseCommandLine(argc, argv);
  using namespace imca;

  if (absl::GetFlag(FLAGS_linger_seconds) < 0) return Fail("--linger_seconds must be >= 0");
  if (const int code = absl::GetFlag(FLAGS_signal_exit_code); code < 0 || code > 255) {
    return Fail("--signal_exit_code must be in [0, 255]");
  }
  auto scenario = ScenarioFromFlags();
  if (!scenario.ok()) return Fail(std::string(scenario.status().message()));

  learner::LearnerConfig config;
  config.ppo.hidden = absl::GetFlag(FLAGS_hidden);
  config.ppo.learning_rate = absl::GetFlag(FLAGS_lr);
  config.ppo.epochs = absl::GetFlag(FLAGS_epochs);
  config.ppo.minibatches = absl::GetFlag(FLAGS_minibatches);
  config.ppo.entropy_coef = absl::GetFlag(FLAGS_entropy_coef);
  config.ppo.clip = absl::GetFlag(FLAGS_clip);
  config.ppo.seed = absl::GetFlag(FLAGS_seed);
  config.ppo.threads = absl::GetFlag(FLAGS_threads);
  config.gamma = absl::GetFlag(FLAGS_gamma);
  config.gamma_int = absl::GetFlag(FLAGS_gamma_int);
  config.lambda = absl::GetFlag(FLAGS_lambda);
  config.intrinsic_coef = absl::GetFlag(FLAGS_intrinsic_coef);
  config.batch_steps = absl::GetFlag(FLAGS_batch_steps);
  config.max_policy_lag = absl::GetFlag(FLAGS_max_policy_lag);
  config.queue_capacity = absl::GetFlag(FLAGS_queue_capacity);
  config.budget_steps = absl::GetFlag(FLAGS_steps);
  config.run_dir = absl::GetFlag(FLAGS_run_dir);
  config.checkpoint_every = absl::GetFlag(FLAGS_checkpoint_every);
  if (absl::GetFlag(FLAGS_max_batch_mb) < 1 || absl::GetFlag(FLAGS_max_batch_mb) > (int64_t{1} << 30)) {
    return Fail("--max_batch_mb must be in [1, 2^30]");
  }
  config.max_batch_bytes = absl::GetFlag(FLAGS_max_batch_mb) * 1000 * 1000;
  auto learner = learner::Learner::Create(scenario->get(), config);
  if (!learner.ok()) return Fail(std::string(learner.status().message()));
  std::string resume = absl::GetFlag(FLAGS_resume);
  if (absl::GetFlag(FLAGS_auto_resume)) {
    if (!resume.empty()) return Fail("--auto_resume and --resume exclude each other");
    if (config.run_dir.empty()) return Fail("--auto_resume needs --run_dir");
    const std::string checkpoints = (std::filesystem::path(config.run_dir) / "checkpoints").string();
    const absl::StatusOr<std::string> newest = learner::NewestCheckpoint(checkpoints);
    if (newest.ok()) {
      resume = checkpoints;
    } else if (!absl::IsNotFound(newest.status())) {
      return Fail(absl::StrCat("--auto_resume: ", newest.status().message()));
    }
  }
  if (!resume.empty()) {
    if (absl::Status restored = (*learner)->Restore(resume); !restored.ok()) {
      return Fail(absl::StrCat("--resume: ", restored.message()));
    }
    std::fprintf(stderr, "learner: resumed at policy version %lld\n",
                 static_cast<long long>((*learner)->Status().policy_version()));
  }

  learner::LearnerServiceImpl service(learner->get());
  InstallShutdownSignalHandlers();
  int port = 0;
  auto server = StartServer(absl::GetFlag(FLAGS_listen), {&service}, &port);
  if (!server.ok()) return Fail(absl::StrCat("--listen: ", server.status().message()));
  if (const std::string port_file = absl::GetFlag(FLAGS_port_file); !port_file.empty()) {
    std::ofstream(port_file) << port << "\n";
  }
  std::fprintf(stderr, "learner: serving on port %d\n", port);

  // Signals only set a flag; this watcher turns it into Learner::Stop().
  std::atomic<bool> finished{false};
  std::thread watcher([&] {
    while (!finished.load() && !ShutdownRequested()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    (*learner)->Stop();
  });
  const absl::Status run = (*learner)->Run();
  finished.store(true);
  watcher.join();
  // After the budget, keep answering for a moment so that actors learn it is
  // done (OUT_OF_RANGE on push, done in GetStatus) instead of retrying.
  const auto linger_end = std::chrono::steady_clock::now() +
                          std::chrono::duration<double>(absl::GetFlag(FLAGS_linger_seconds));
  while (run.ok() && (*learner)->Status().done() && !ShutdownRequested() &&
         std::chrono::steady_clock::now() < linger_end) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  (*server)->Shutdown(DeadlineIn(std::chrono::seconds(3)));
  if (!run.ok()) return Fail(absl::StrCat("training failed: ", run.message()));
  const v1::LearnerStatus status = (*learner)->Status();
  std::fprintf(stderr, "learner: stopped at %lld env steps, policy version %lld\n",
               static_cast<long long>(status.env_steps()),
               static_cast<long long>(status.policy_version()));
  return status.done() ? 0 : absl::GetFlag(FLAGS_signal_exit_code);
}
