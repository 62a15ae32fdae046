#include "learner/algorithms/cmae/cmae.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>
#include <utility>

#include "absl/container/flat_hash_map.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/base/atomic_file.h"
#include "common/base/lap.h"
#include "common/base/rng.h"
#include "common/base/status_macros.h"
#include "learner/algorithms/registry.h"

namespace imca::learner {

using cmae::QTable;
using cmae::ReadPod;
using cmae::Replay;
using cmae::Subspaces;
using cmae::Transition;
using cmae::WritePod;

namespace {

constexpr char kTag[] = "IMCA-CMAE-2";

// An environment's episode so far, as far as the learner saw it unbroken.
struct OpenEpisode {
  uint64_t incarnation = 0;
  int64_t episode_id = -1;
  std::vector<Transition> steps;
};

}  // namespace

struct Cmae::Impl {
  Impl(const env::Scenario* scenario, const LearnerConfig& config, env::JointStateSpace space)
      : scenario(scenario),
        config(config),
        space(std::move(space)),
        n(scenario->num_agents()),
        num_actions(scenario->num_actions()),
        subspaces(this->space.ranges(), this->space.joint_actions(), c.tracked, c.recip_t, c.entropy_every),
        replay(c.replay),
        goal_replay(c.replay),
        rng(NamedSeed(config.seed, "cmae", 0)) {
    for (int k = 0; k < n; ++k) {
      explore.emplace_back(num_actions);
      exploit.emplace_back(num_actions);
    }
  }

  void AddStep(const std::string& actor, uint64_t incarnation, int env, int64_t episode_id, const Transition& t);
  void EndEpisode(OpenEpisode& episode);
  double Weight() const {
    return c.total_episodes > 0 ? std::min(1.0, static_cast<double>(episodes) / c.total_episodes) : 1.0;
  }
  void Write(std::ostream& out) const;
  absl::Status Read(std::istream& in);

  const env::Scenario* scenario;
  const LearnerConfig config;
  const CmaeConfig& c = OptionsOf<CmaeConfig>(config);
  const env::JointStateSpace space;
  const int n;
  const int num_actions;
  std::vector<QTable> explore, exploit;
  Subspaces subspaces;
  Replay replay;       // Every transition: the tables' data.
  Replay goal_replay;  // The goal sampler's (the meta learner's replay).
  absl::flat_hash_map<int64_t, uint32_t> joint_counts;  // state * joint actions + joint action.
  Rng rng;
  int64_t episodes = 0;
  std::pair<int64_t, int64_t> goal{-1, -1};
  std::map<std::pair<std::string, int>, OpenEpisode> open;  // By (actor id, env).

  // This iteration's.
  int64_t it_goals = 0, it_goals_reached = 0, it_updates = 0, it_rows = 0;
  double it_seconds = 0, it_entropy = 0;
};

void Cmae::Impl::AddStep(const std::string& actor, uint64_t incarnation, int env, int64_t episode_id,
                         const Transition& t) {
  OpenEpisode& episode = open[{actor, env}];
  if (episode.incarnation != incarnation || episode.episode_id != episode_id ||
      (!episode.steps.empty() && episode.steps.back().next_state != t.state)) {
    // Not the steps' continuation: the actor restarted (its environments
    // began anew), or went back with the learner to a checkpoint and acted
    // on. What was seen of the old episode is dropped, unseen by the
    // tables; the rest enters as an episode of its own.
    episode.steps.clear();
    episode.incarnation = incarnation;
    episode.episode_id = episode_id;
  }
  episode.steps.push_back(t);
  if (t.done) EndEpisode(episode);
}

void Cmae::Impl::EndEpisode(OpenEpisode& episode) {
  // Its steps, in order, are counted (every tracked restricted space, and
  // the joint count the goal replay's threshold reads) and stored: CMAE
  // does both per step, the same with one environment, and only steps of
  // whole episodes are counted here.
  std::vector<int32_t> vars(space.num_vars());
  for (const Transition& t : episode.steps) {
    space.Decode(t.state, vars.data());
    subspaces.Count(vars.data(), t.joint_action);
    const uint32_t seen = ++joint_counts[t.state * space.joint_actions() + t.joint_action];
    replay.Insert(t);
    if (seen < c.insert_threshold) goal_replay.Insert(t);
  }
  episode.steps.clear();
  ++episodes;

  // The goal: a least-counted (state, joint action) of the chosen
  // restricted space among sampled goal-replay states.
  const std::vector<int64_t> samples = goal_replay.SampleDistinct(c.goal_samples, rng);
  auto vars_of = [&](int i, int32_t* vars) { space.Decode(goal_replay.at(samples[i]).state, vars); };
  auto each_step = [&](const std::function<void(const int32_t*, int64_t)>& visit) {
    for (int64_t i = 0; i < goal_replay.size(); ++i) {
      space.Decode(goal_replay.at(i).state, vars.data());
      visit(vars.data(), goal_replay.at(i).joint_action);
    }
  };
  const std::optional<std::pair<int, int64_t>> chosen =
      subspaces.Goal(static_cast<int>(samples.size()), vars_of, each_step, rng);

  // The exploitation tables: a batch led by the first successful episode.
  for (int k = 0; k < n; ++k) {
    for (int64_t slot : replay.PrioritizedBatch(c.batch, rng)) {
      const Transition& t = replay.at(slot);
      exploit[k].Update(t.state, space.AgentAction(t.joint_action, k), t.reward, t.next_state, t.done, c.exploit_lr,
                        c.gamma);
      ++it_updates;
    }
  }

  // The exploration tables: anew, on the replay's way into the goal.
  for (QTable& table : explore) table.Clear();
  if (!chosen.has_value()) return;
  goal = {goal_replay.at(samples[chosen->first]).state, chosen->second};
  ++it_goals;
  const auto trajectory = replay.GoalTrajectory(goal.first);
  if (!trajectory.has_value()) return;
  ++it_goals_reached;
  const std::vector<int64_t>& before = trajectory->first;
  for (int k = 0; k < n; ++k) {
    const int goal_action = space.AgentAction(goal.second, k);
    // The hallucinated terminal goal transition, then the way back.
    explore[k].Update(goal.first, goal_action, 1, goal.first, true, c.explore_lr, c.gamma);
    for (auto it = before.rbegin(); it != before.rend(); ++it) {
      const Transition& t = replay.at(*it);
      const int a = space.AgentAction(t.joint_action, k);
      const double r = t.state == goal.first && a == goal_action ? 1 : 0;
      explore[k].Update(t.state, a, r, t.next_state, t.done, c.explore_lr, c.gamma);
    }
    it_updates += 1 + static_cast<int64_t>(before.size());
  }
}

void Cmae::Impl::Write(std::ostream& out) const {
  out << kTag << "\n";
  WritePod(out, static_cast<int32_t>(space.num_vars()));
  for (int64_t r : space.ranges()) WritePod(out, r);
  WritePod(out, space.joint_actions());
  WritePod(out, episodes);
  WritePod(out, goal.first);
  WritePod(out, goal.second);
  for (uint64_t word : rng.State()) WritePod(out, word);
  for (const QTable& t : explore) t.Write(out);
  for (const QTable& t : exploit) t.Write(out);
  std::vector<std::pair<int64_t, uint32_t>> counts(joint_counts.begin(), joint_counts.end());
  std::sort(counts.begin(), counts.end());
  WritePod(out, static_cast<int64_t>(counts.size()));
  for (const auto& [key, count] : counts) {
    WritePod(out, key);
    WritePod(out, count);
  }
  subspaces.Write(out);
  replay.Write(out);
  goal_replay.Write(out);
  WritePod(out, static_cast<int64_t>(open.size()));
  for (const auto& [key, episode] : open) {
    WritePod(out, static_cast<int64_t>(key.first.size()));
    out.write(key.first.data(), static_cast<std::streamsize>(key.first.size()));
    WritePod(out, static_cast<int32_t>(key.second));
    WritePod(out, episode.incarnation);
    WritePod(out, episode.episode_id);
    WritePod(out, static_cast<int64_t>(episode.steps.size()));
    for (const Transition& t : episode.steps) t.Write(out);
  }
}

absl::Status Cmae::Impl::Read(std::istream& in) {
  std::string tag;
  if (!std::getline(in, tag) || tag != kTag) {
    return absl::InvalidArgumentError(absl::StrCat("checkpoint: not CMAE's (", kTag, ")"));
  }
  int32_t vars = 0;
  if (!ReadPod(in, &vars)) return absl::DataLossError("checkpoint: CMAE's header cut short");
  std::vector<int64_t> ranges(std::max(vars, 0));
  for (int64_t& r : ranges) {
    if (!ReadPod(in, &r)) return absl::DataLossError("checkpoint: CMAE's header cut short");
  }
  int64_t joint_actions = 0;
  if (!ReadPod(in, &joint_actions)) return absl::DataLossError("checkpoint: CMAE's header cut short");
  if (ranges != space.ranges() || joint_actions != space.joint_actions()) {
    return absl::InvalidArgumentError("checkpoint: CMAE's tables of another scenario (joint state variables differ)");
  }
  std::array<uint64_t, 4> words{};
  if (!ReadPod(in, &episodes) || !ReadPod(in, &goal.first) || !ReadPod(in, &goal.second)) {
    return absl::DataLossError("checkpoint: CMAE's counters cut short");
  }
  for (uint64_t& word : words) {
    if (!ReadPod(in, &word)) return absl::DataLossError("checkpoint: CMAE's generator cut short");
  }
  rng.SetState(words);
  for (QTable& t : explore) IMCA_RETURN_IF_ERROR(t.Read(in));
  for (QTable& t : exploit) IMCA_RETURN_IF_ERROR(t.Read(in));
  int64_t counts = 0;
  if (!ReadPod(in, &counts) || counts < 0) return absl::DataLossError("checkpoint: joint counts cut short");
  joint_counts.reserve(counts);
  for (int64_t i = 0; i < counts; ++i) {
    int64_t key = 0;
    uint32_t count = 0;
    if (!ReadPod(in, &key) || !ReadPod(in, &count)) return absl::DataLossError("checkpoint: joint counts cut short");
    joint_counts.emplace(key, count);
  }
  IMCA_RETURN_IF_ERROR(subspaces.Read(in));
  IMCA_RETURN_IF_ERROR(replay.Read(in));
  IMCA_RETURN_IF_ERROR(goal_replay.Read(in));
  int64_t episodes_open = 0;
  if (!ReadPod(in, &episodes_open) || episodes_open < 0) return absl::DataLossError("checkpoint: open episodes cut short");
  for (int64_t i = 0; i < episodes_open; ++i) {
    int64_t length = 0, steps = 0;
    int32_t env = 0;
    if (!ReadPod(in, &length) || length < 0 || length > 4096) return absl::DataLossError("checkpoint: open episodes");
    std::string actor(length, '\0');
    OpenEpisode episode;
    if (!in.read(actor.data(), length) || !ReadPod(in, &env) || !ReadPod(in, &episode.incarnation) ||
        !ReadPod(in, &episode.episode_id) || !ReadPod(in, &steps) || steps < 0) {
      return absl::DataLossError("checkpoint: open episodes cut short");
    }
    for (int64_t s = 0; s < steps; ++s) {
      Transition t;
      if (!t.Read(in)) return absl::DataLossError("checkpoint: open episodes cut short");
      episode.steps.push_back(t);
    }
    open.emplace(std::make_pair(std::move(actor), env), std::move(episode));
  }
  return absl::OkStatus();
}

double Cmae::TableBytes(const env::JointStateSpace& space, const LearnerConfig& config) {
  const CmaeConfig& c = OptionsOf<CmaeConfig>(config);
  // A replay slot: the transition, its time stamp and its place in the
  // index; two replays.
  const double replay = 2.0 * static_cast<double>(c.replay) * (sizeof(Transition) + 4 + 24);
  double states = static_cast<double>(space.size());
  if (config.budget_steps > 0) states = std::min(states, static_cast<double>(config.budget_steps));
  // Per state visited: a row of 2n tables (key, values, hash slack), the
  // joint count and a count in each tracked space and single variable.
  const double row = 2.0 * space.num_agents() * (8 + 8 * cmae::kMaxActions) * 1.25;
  const double counts = 16 * 1.25 * (1 + c.tracked + space.num_vars());
  return replay + states * (row + counts);
}

Cmae::Cmae(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Cmae::~Cmae() = default;

absl::StatusOr<std::unique_ptr<Cmae>> Cmae::Create(const env::Scenario* scenario, const LearnerConfig& config) {
  IMCA_ASSIGN_OR_RETURN(const CmaeConfig* options, CheckedOptions<CmaeConfig>(config));
  const CmaeConfig& c = *options;
  if (!(c.gamma >= 0 && c.gamma <= 1)) return absl::InvalidArgumentError("cmae.gamma (--cmae_gamma) must be in [0, 1]");
  if (!(c.explore_lr > 0 && c.explore_lr <= 1) || !(c.exploit_lr > 0 && c.exploit_lr <= 1)) {
    return absl::InvalidArgumentError("cmae.explore_lr and exploit_lr (--cmae_explore_lr, --cmae_exploit_lr) must be in (0, 1]");
  }
  if (c.replay < 1 || c.replay > (int64_t{1} << 31)) {
    return absl::InvalidArgumentError("cmae.replay (--cmae_replay) must be in [1, 2^31]");
  }
  if (c.total_episodes < 0) return absl::InvalidArgumentError("cmae.total_episodes (--cmae_episodes) must be >= 0");
  if (c.goal_samples < 1 || c.batch < 0 || c.entropy_every < 1 || c.tracked < 1) {
    return absl::InvalidArgumentError(
        "cmae.goal_samples, entropy_every and tracked (--cmae_goal_samples, --cmae_entropy_every, --cmae_tracked) "
        "must be >= 1 and cmae.batch (--cmae_batch) >= 0");
  }
  if (!(c.recip_t >= 0) || !std::isfinite(c.recip_t)) {
    return absl::InvalidArgumentError("cmae.recip_t (--cmae_recip_t) must be finite and >= 0");
  }
  if (c.insert_threshold < 1) return absl::InvalidArgumentError("cmae.insert_threshold (--cmae_insert_threshold) must be >= 1");
  if (c.max_table_mb < 1) return absl::InvalidArgumentError("cmae.max_table_mb (--cmae_max_table_mb) must be >= 1");
  if (scenario->num_actions() > cmae::kMaxActions) {
    return absl::InvalidArgumentError(absl::StrCat("cmae: ", scenario->name(), " has ", scenario->num_actions(),
                                                   " actions, more than the ", cmae::kMaxActions, " its tables hold"));
  }
  absl::StatusOr<env::JointStateSpace> joint = env::JointStateSpace::Create(*scenario);
  if (!joint.ok()) return absl::InvalidArgumentError(absl::StrCat("cmae: ", joint.status().message()));
  env::JointStateSpace space = *std::move(joint);
  if (space.num_vars() > 32) {
    return absl::InvalidArgumentError(absl::StrCat("cmae: ", scenario->name(), " has ", space.num_vars(),
                                                   " state variables, more than the 32 its restricted spaces index"));
  }
  if (const double bytes = TableBytes(space, config); bytes > static_cast<double>(c.max_table_mb) * 1e6) {
    return absl::InvalidArgumentError(absl::StrFormat(
        "cmae: the tables of %s could reach %.0f MB (%.3g joint states, %d agents), over --cmae_max_table_mb %d",
        scenario->name(), bytes / 1e6, static_cast<double>(space.size()), scenario->num_agents(), c.max_table_mb));
  }
  return std::unique_ptr<Cmae>(new Cmae(std::make_unique<Impl>(scenario, config, std::move(space))));
}

FeaturisedUnroll Cmae::Featurise(v1::Unroll unroll) const {
  FeaturisedUnroll f;
  f.unroll = std::move(unroll);
  return f;
}

int64_t Cmae::IterationBytes(int64_t steps) const {
  // The queued unrolls' states, actions and rewards; the tables are bounded by TableBytes.
  const int64_t k = impl_->scenario->state_size(), n = impl_->n;
  return steps * (2 * k + 2 * n) * 4;
}

absl::Status Cmae::Add(const FeaturisedUnroll& queued) {
  Clock::time_point start = Clock::now();
  Impl& m = *impl_;
  const v1::Unroll& u = queued.unroll;
  const int T = u.length(), E = u.num_envs(), n = m.n, K = u.state_size();
  std::vector<int32_t> actions(n);
  for (int t = 0; t < T; ++t) {
    for (int e = 0; e < E; ++e) {
      const int64_t row = static_cast<int64_t>(t) * E + e;
      Transition step;
      step.state = m.space.Index(u.states().data() + row * K);
      step.next_state = m.space.Index(u.next_states().data() + row * K);
      for (int a = 0; a < n; ++a) actions[a] = u.actions(static_cast<int>(row * n + a));
      step.joint_action = m.space.JointAction(actions.data());
      double reward = 0;
      for (int a = 0; a < n; ++a) reward += u.rewards(static_cast<int>(row * n + a));
      step.reward = reward / n;
      step.done = u.terminated(static_cast<int>(row)) || u.truncated(static_cast<int>(row));
      m.AddStep(u.actor_id(), u.incarnation(), e, u.episode_ids(static_cast<int>(row)), step);
    }
  }
  // The acting policy's entropy, from the probabilities the actor acted
  // with (greedy, ties shared: ln of the tied actions).
  const int A = u.num_actions();
  for (int i = 0; i + A <= u.action_probs_size(); i += A) {
    for (int j = 0; j < A; ++j) {
      const float p = u.action_probs(i + j);
      if (p > 0) m.it_entropy -= p * std::log(p);
    }
    ++m.it_rows;
  }
  m.it_seconds += Lap(start);
  return absl::OkStatus();
}

absl::StatusOr<IterationStats> Cmae::Train() {
  Impl& m = *impl_;
  IterationStats stats;
  const Subspaces::Mask chosen = m.subspaces.chosen();
  stats.values = {
      {"cmae_episodes", static_cast<double>(m.episodes)},
      {"cmae_exploit_weight", m.Weight()},
      {"cmae_goals_reached", m.it_goals > 0 ? static_cast<double>(m.it_goals_reached) / m.it_goals : 0},
      {"cmae_space_vars", static_cast<double>(__builtin_popcount(chosen))},
      {"cmae_space_entropy", m.subspaces.NormalisedEntropy(chosen)},
      {"cmae_exploit_states", static_cast<double>(m.exploit[0].NonzeroStates().size())},
      {"cmae_replay", static_cast<double>(m.replay.size())},
  };
  stats.updates = m.it_updates;
  stats.seconds_copy = m.it_seconds;
  stats.entropy = m.it_rows > 0 ? m.it_entropy / m.it_rows : 0;
  m.it_goals = m.it_goals_reached = m.it_updates = m.it_rows = 0;
  m.it_seconds = m.it_entropy = 0;
  return stats;
}

v1::Policy Cmae::ExportPolicy(int64_t version) const {
  const Impl& m = *impl_;
  v1::Policy policy;
  policy.set_version(version);
  policy.set_architecture(v1::Policy::TABULAR_Q);
  policy.set_num_actions(m.num_actions);
  v1::TabularPolicy* t = policy.mutable_tabular();
  t->set_num_agents(m.n);
  t->set_exploit_weight(m.Weight());
  t->set_joint_states(m.space.size());
  auto fill = [&](const std::vector<QTable>& tables, v1::QTable* out) {
    std::vector<int64_t> states;
    for (const QTable& table : tables) {
      const std::vector<int64_t> nonzero = table.NonzeroStates();
      states.insert(states.end(), nonzero.begin(), nonzero.end());
    }
    std::sort(states.begin(), states.end());
    states.erase(std::unique(states.begin(), states.end()), states.end());
    out->mutable_states()->Add(states.begin(), states.end());
    out->mutable_values()->Reserve(static_cast<int>(states.size()) * m.n * m.num_actions);
    for (int64_t s : states) {
      for (const QTable& table : tables) {
        for (int a = 0; a < m.num_actions; ++a) out->add_values(table.Value(s, a));
      }
    }
  };
  fill(m.explore, t->mutable_explore());
  fill(m.exploit, t->mutable_exploit());
  return policy;
}

absl::Status Cmae::Save(const std::string& path) const {
  return WriteFileAtomically(path, [this](std::ostream& out) {
    impl_->Write(out);
    return out ? absl::OkStatus() : absl::InternalError("writing CMAE's state failed");
  });
}

absl::Status Cmae::Load(const std::string& path) {
  IMCA_ASSIGN_OR_RETURN(const std::string bytes, ReadFile(path, "CMAE checkpoint"));
  auto fresh = std::make_unique<Impl>(impl_->scenario, impl_->config, impl_->space);
  std::istringstream in(bytes);
  IMCA_RETURN_IF_ERROR(fresh->Read(in));
  impl_ = std::move(fresh);
  return absl::OkStatus();
}

const env::JointStateSpace& Cmae::space() const { return impl_->space; }
int64_t Cmae::episodes() const { return impl_->episodes; }
double Cmae::exploit_weight() const { return impl_->Weight(); }
const cmae::QTable& Cmae::explore(int agent) const { return impl_->explore[agent]; }
const cmae::QTable& Cmae::exploit(int agent) const { return impl_->exploit[agent]; }
const cmae::Subspaces& Cmae::subspaces() const { return impl_->subspaces; }
const cmae::Replay& Cmae::replay() const { return impl_->replay; }
std::pair<int64_t, int64_t> Cmae::goal() const { return impl_->goal; }

}  // namespace imca::learner
