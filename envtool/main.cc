// imca_env: renders, plays and scripts environments (docs/envtool.md).
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <functional>
#include <optional>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/flags/usage.h"
#include "absl/flags/usage_config.h"
#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "common/base/rng.h"
#include "common/env/env.h"
#include "common/env/scenario_flags.h"
#include "common/protocol/acting_policy.h"
#include "common/protocol/policy_mlp.h"
#include "envtool/episode_io.h"
#include "envtool/render.h"

ABSL_FLAG(uint64_t, seed, 1, "seed of Reset and of the scenario's random draws");
ABSL_FLAG(std::string, state, "", "start from this state \"z,c1,...,t\" instead of a Reset");
ABSL_FLAG(std::string, out, "", "render: the PNG file to write");
ABSL_FLAG(int, cell_px, 24, "pixels per cell in PNG and GIF pictures");
ABSL_FLAG(std::string, actions, "",
          "script: action file, one step per line (--actions=- reads standard input)");
ABSL_FLAG(bool, json, false, "play, script: print one JSON object per line per state instead of the grid");
ABSL_FLAG(std::string, gif, "", "play, script: save the episode as an animated GIF");
ABSL_FLAG(int, gif_delay_cs, 40, "GIF frame delay in hundredths of a second");
ABSL_FLAG(std::string, policy, "", "rollout: a policy.pb written by the learner (imca.v1.Policy)");

namespace imca::envtool {
namespace {

constexpr int kRuntimeError = 1;  // Could not write an output file.
constexpr int kUsageError = 2;    // Bad command, flag, map, state or action input.
constexpr const char* kActionNames[] = {"up", "down", "left", "right", "stay"};

int Fail(int code, absl::string_view message) {
  std::fprintf(stderr, "imca_env: %s\n", std::string(message).c_str());
  return code;
}

std::string Usage() {
  return absl::StrCat(
      "renders, plays and scripts an IMCA environment (docs/envtool.md).\n"
      "  imca_env render --out FILE.png [--seed N | --state z,c1,...,t]\n"
      "  imca_env play   [--json] [--gif FILE.gif]     one line per step from stdin, q quits\n"
      "  imca_env script --actions FILE [--json] [--gif FILE.gif]\n"
      "  imca_env rollout --policy RUN/policy.pb [--json] [--gif FILE.gif]   one episode of a trained policy\n"
      "Each step is one key per agent: w up, s down, a left, d right, x stay (or numbers 0..A-1).\n"
      "Scenarios (--scenario): ",
      absl::StrJoin(env::ScenarioNames(), ", "), "; maps: --map (default maps/<scenario>.txt).");
}

// One episode: its state and random draws, printing each state as text or
// JSON and adding a frame per state to the GIF, if any. Not thread-safe.
class Episode {
 public:
  // `annotate`, if set, returns JSON fields (",\"key\":value...") added to
  // each state's JSON line.
  using Annotate = std::function<std::string(const int32_t* state)>;

  // `rng` draws the scenario's random moves from `state` on.
  Episode(const env::Scenario& scenario, const Renderer& renderer, std::vector<int32_t> state, Rng rng,
          bool json, GifWriter* gif, Annotate annotate = nullptr)
      : scenario_(scenario),
        renderer_(renderer),
        state_(std::move(state)),
        rng_(rng),
        json_(json),
        gif_(gif),
        annotate_(std::move(annotate)),
        rewards_(scenario.num_agents()) {}

  bool over() const { return outcome_.terminated || outcome_.truncated; }
  const int32_t* state() const { return state_.data(); }
  int t() const { return state_[scenario_.step_index()]; }

  // Prints the initial state. Call once, before Step.
  void Start() { Show({}, {}); }
  // Steps with one action per agent (each in [0, num_actions)) and prints
  // the new state. Must not be called once over().
  void Step(const std::vector<int32_t>& actions) {
    outcome_ = scenario_.Step(state_.data(), actions.data(), rng_, rewards_.data());
    Show(actions, rewards_);
  }

  // The first error of adding a frame to the GIF.
  const absl::Status& gif_status() const { return gif_status_; }

 private:
  void Show(const std::vector<int32_t>& actions, const std::vector<float>& rewards) {
    if (gif_ != nullptr && gif_status_.ok()) gif_status_ = gif_->AddFrame(renderer_.Draw(state_.data()));
    if (json_) {
      std::string line = StateJson(scenario_, state_.data(), actions, rewards, outcome_);
      if (annotate_) line.insert(line.size() - 1, annotate_(state_.data()));
      std::printf("%s\n", line.c_str());
    } else {
      if (!actions.empty()) {
        std::vector<const char*> names;
        for (int32_t u : actions) names.push_back(kActionNames[u]);
        std::printf("actions: %s   rewards: %s\n", absl::StrJoin(names, " ").c_str(),
                    absl::StrJoin(rewards, " ").c_str());
      }
      std::printf("%s", scenario_.Render(state_.data()).c_str());
      if (over()) {
        std::printf("episode over at t=%d: %s\n", t(),
                    outcome_.success      ? "success"
                    : outcome_.terminated ? "failure"
                                          : "step limit reached");
      }
    }
    std::fflush(stdout);
  }

  const env::Scenario& scenario_;
  const Renderer& renderer_;
  std::vector<int32_t> state_;
  Rng rng_;
  const bool json_;
  GifWriter* const gif_;  // Null: no --gif.
  const Annotate annotate_;
  absl::Status gif_status_;
  std::vector<float> rewards_;
  env::StepOutcome outcome_;
};

void Play(Episode& episode, const env::Scenario& scenario, bool json) {
  const bool prompt = !json && isatty(STDIN_FILENO);
  if (prompt) {
    std::printf("one key per agent (%d) per line: w up, s down, a left, d right%s; q quits\n",
                scenario.num_agents(), scenario.num_actions() > env::kStay ? ", x stay" : "");
  }
  episode.Start();
  std::string line;
  while (!episode.over()) {
    if (prompt) {
      std::printf("> ");
      std::fflush(stdout);
    }
    if (!std::getline(std::cin, line) || absl::StripAsciiWhitespace(line) == "q") break;
    auto actions = ParseActionLine(line, scenario.num_agents(), scenario.num_actions());
    if (!actions.ok()) {
      const std::string message(actions.status().message());
      std::printf(json ? "{\"error\":%s}\n" : "%s\n", json ? JsonString(message).c_str() : message.c_str());
      std::fflush(stdout);
      continue;
    }
    episode.Step(*actions);
  }
}

void Script(Episode& episode, const std::vector<std::vector<int32_t>>& steps) {
  episode.Start();
  size_t used = 0;
  while (used < steps.size() && !episode.over()) episode.Step(steps[used++]);
  if (used < steps.size()) {
    std::fprintf(stderr, "imca_env: the episode ended at t=%d; %zu later action lines not used\n",
                 episode.t(), steps.size() - used);
  }
}

// The action probabilities of `policy` in a state, [n][A], as an actor's
// evaluation environments act (the same for a network; CMAE's Q-tables act
// on their exploitation side).
class PolicyProbs {
 public:
  PolicyProbs(const env::Scenario& scenario, ActingPolicy& policy)
      : policy_(policy),
        n_(scenario.num_agents()),
        state_size_(scenario.state_size()),
        probs_(static_cast<size_t>(n_) * scenario.num_actions()) {}

  // The probabilities in `state` (computed once per state: a rollout's JSON
  // line and its next actions ask for the same).
  const std::vector<float>& Of(const int32_t* state) {
    if (!last_.empty() && std::equal(last_.begin(), last_.end(), state)) return probs_;
    policy_.Probabilities(state, 1, /*evaluation=*/true, probs_.data());
    last_.assign(state, state + state_size_);
    return probs_;
  }

  // ',"probs":[[p00,...],...]' of `state`, each read back bit for bit (FloatJson).
  std::string Json(const int32_t* state) {
    const std::vector<float>& probs = Of(state);
    const int a_count = static_cast<int>(probs.size()) / n_;
    std::string out = ",\"probs\":[";
    for (int a = 0; a < n_; ++a) {
      absl::StrAppend(&out, a ? ",[" : "[");
      for (int j = 0; j < a_count; ++j) {
        absl::StrAppend(&out, j ? "," : "", FloatJson(probs[a * a_count + j]));
      }
      absl::StrAppend(&out, "]");
    }
    return out + "]";
  }

 private:
  ActingPolicy& policy_;
  const int n_;
  const int state_size_;
  std::vector<float> probs_;
  std::vector<int32_t> last_;  // The state probs_ are of (empty: none yet).
};

// One episode with actions sampled from `policy`, as an actor would.
void Rollout(Episode& episode, const env::Scenario& scenario, PolicyProbs& policy, uint64_t seed) {
  const int n = scenario.num_agents(), a_count = scenario.num_actions();
  std::vector<int32_t> actions(n);
  Rng rng(ActionSamplingSeed(seed));
  episode.Start();
  while (!episode.over()) {
    const std::vector<float>& probs = policy.Of(episode.state());
    for (int a = 0; a < n; ++a) actions[a] = SampleCategorical(&probs[a * a_count], a_count, rng.UniformDouble());
    episode.Step(actions);
  }
}

absl::StatusOr<ActingPolicy> LoadPolicy(const std::string& path, const env::Scenario& scenario) {
  std::ifstream in(path, std::ios::binary);
  v1::Policy proto;
  if (!in || !proto.ParseFromIstream(&in)) {
    return absl::InvalidArgumentError(absl::StrCat("cannot read a policy from '", path, "'"));
  }
  absl::StatusOr<ActingPolicy> policy = ActingPolicy::FromProto(proto, scenario);
  if (!policy.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("'", path, "' does not fit ", scenario.name(),
                                                   " (another scenario or map?): ", policy.status().message()));
  }
  return policy;
}

int Main(const std::vector<char*>& args) {
  if (args.size() != 2) return Fail(kUsageError, "expected one command: render, play, script or rollout (--help)");
  const std::string command = args[1];
  if (command != "render" && command != "play" && command != "script" && command != "rollout") {
    return Fail(kUsageError, absl::StrCat("unknown command '", command, "' (render, play, script, rollout)"));
  }
  auto scenario_or = ScenarioFromFlags();
  if (!scenario_or.ok()) return Fail(kUsageError, scenario_or.status().message());
  const env::Scenario& scenario = **scenario_or;
  auto renderer = Renderer::Create(&scenario, absl::GetFlag(FLAGS_cell_px));
  if (!renderer.ok()) return Fail(kUsageError, absl::StrCat("--cell_px: ", renderer.status().message()));

  // The stream of the scenario's draws: a VecEnv environment's (env::VecEnv::
  // EnvSeed), so --seed with that value plays its episode; from --state the
  // draws start afresh from the seed, as the environment's after a reset to
  // given states.
  const uint64_t seed = absl::GetFlag(FLAGS_seed);
  Rng rng(seed);
  std::vector<int32_t> state(scenario.state_size());
  if (const std::string text = absl::GetFlag(FLAGS_state); !text.empty()) {
    auto parsed = ParseState(text, scenario);
    if (!parsed.ok()) return Fail(kUsageError, absl::StrCat("--state: ", parsed.status().message()));
    state = *std::move(parsed);
  } else {
    scenario.Reset(rng, state.data());
  }

  if (command == "render") {
    const std::string out = absl::GetFlag(FLAGS_out);
    if (out.empty()) return Fail(kUsageError, "--out: the PNG file to write is required");
    const absl::Status written = WritePng(renderer->Draw(state.data()), out);
    if (!written.ok()) return Fail(kRuntimeError, written.message());
    std::printf("wrote %s (%dx%d px)\n", out.c_str(), renderer->width(), renderer->height());
    return 0;
  }

  std::vector<std::vector<int32_t>> steps;
  if (command == "script") {
    const std::string path = absl::GetFlag(FLAGS_actions);
    if (path.empty()) return Fail(kUsageError, "--actions: the action file is required");
    auto parsed = ReadActionFile(path, scenario.num_agents(), scenario.num_actions());
    if (!parsed.ok()) return Fail(kUsageError, parsed.status().message());
    steps = *std::move(parsed);
  }
  std::optional<ActingPolicy> policy;
  if (command == "rollout") {
    const std::string path = absl::GetFlag(FLAGS_policy);
    if (path.empty()) return Fail(kUsageError, "--policy: the policy.pb file is required");
    auto loaded = LoadPolicy(path, scenario);
    if (!loaded.ok()) return Fail(kUsageError, absl::StrCat("--policy: ", loaded.status().message()));
    policy.emplace(*std::move(loaded));
  }
  const int delay_cs = absl::GetFlag(FLAGS_gif_delay_cs);
  if (delay_cs < 1 || delay_cs > 65535) return Fail(kUsageError, "--gif_delay_cs: not in [1, 65535]");
  std::unique_ptr<GifWriter> gif;
  if (const std::string path = absl::GetFlag(FLAGS_gif); !path.empty()) {
    auto created = GifWriter::Create(path, renderer->width(), renderer->height(), delay_cs);
    if (!created.ok()) return Fail(kRuntimeError, created.status().message());
    gif = *std::move(created);
  }
  const bool json = absl::GetFlag(FLAGS_json);
  std::optional<PolicyProbs> probs;
  Episode::Annotate annotate;
  if (policy) {
    probs.emplace(scenario, *policy);
    annotate = [&probs](const int32_t* state) { return probs->Json(state); };
  }
  Episode episode(scenario, *renderer, std::move(state), rng, json, gif.get(), std::move(annotate));
  if (command == "play") {
    Play(episode, scenario, json);
  } else if (command == "rollout") {
    Rollout(episode, scenario, *probs, seed);
  } else {
    Script(episode, steps);
  }
  if (gif == nullptr) return 0;
  absl::Status written = episode.gif_status();
  if (written.ok()) written = gif->Close();
  if (!written.ok()) return Fail(kRuntimeError, written.message());
  std::fprintf(stderr, "imca_env: wrote %s (%d frames)\n", absl::GetFlag(FLAGS_gif).c_str(),
               gif->num_frames());
  return 0;
}

}  // namespace
}  // namespace imca::envtool

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(imca::envtool::Usage());
  // --help lists this file's flags and the scenario flags (absl's default
  // matches files named after the program).
  absl::FlagsUsageConfig usage;
  usage.contains_help_flags = usage.contains_helpshort_flags = [](absl::string_view file) {
    return absl::EndsWith(file, "envtool/main.cc") || absl::EndsWith(file, "common/env/scenario_flags.cc");
  };
  absl::SetFlagsUsageConfig(usage);
  return imca::envtool::Main(absl::ParseCommandLine(argc, argv));
}
