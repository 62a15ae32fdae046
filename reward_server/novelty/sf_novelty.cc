#include "reward_server/novelty/sf_novelty.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>

#include "absl/container/flat_hash_map.h"
#include "absl/strings/str_cat.h"
#include "common/base/lap.h"
#include "common/base/rng.h"
#include "common/base/status_macros.h"
#include "common/nn/archive.h"
#include "common/nn/mlp.h"
#include "reward_server/novelty/joint_input.h"

namespace imca::reward {
namespace {

constexpr char kMagic[] = "IMCA-SF-1";
// Episodic visit counts are kept for two generations of this many requests.
constexpr int64_t kGenerationRequests = 2000;

std::vector<int64_t> Sizes(int64_t in, const SfConfig& config) {
  std::vector<int64_t> sizes = {in};
  for (int h : config.hidden) sizes.push_back(h);
  sizes.push_back(config.features);
  return sizes;
}

// phi (fixed), psi (trained) and psi's target copy.
struct SfModel {
  // phi and psi draw their initial weights from streams 1 and 2 of `seed`.
  SfModel(int64_t in, const SfConfig& config, uint64_t seed)
      : phi(nn::MlpOptions(Sizes(in, config)).seed(nn::SubSeed(seed, 1))),
        psi(nn::MlpOptions(Sizes(in, config)).seed(nn::SubSeed(seed, 2))),
        psi_target(nn::MlpOptions(Sizes(in, config))) {
    for (auto& p : phi->parameters()) p.set_requires_grad(false);
    for (auto& p : psi_target->parameters()) p.set_requires_grad(false);
    SyncTarget();
    optimizer = std::make_unique<torch::optim::Adam>(psi->parameters(),
                                                     torch::optim::AdamOptions(config.learning_rate));
  }

  void SyncTarget() { nn::SoftUpdate(*psi_target, *psi, /*tau=*/1.0); }

  torch::Tensor Psi(const torch::Tensor& x) {
    torch::NoGradGuard no_grad;
    return psi->forward(x);
  }

  // One TD step: psi(x) -> phi(x) + gamma * alive * psi'(next).
  void Train(const torch::Tensor& x, const torch::Tensor& next, const torch::Tensor& alive, double gamma) {
    torch::Tensor goal;
    {
      torch::NoGradGuard no_grad;
      goal = phi->forward(x) + gamma * alive.unsqueeze(1) * psi_target->forward(next);
    }
    optimizer->zero_grad();
    const torch::Tensor loss = (psi->forward(x) - goal).pow(2).sum(1).mean();
    loss.backward();
    optimizer->step();
  }

  void Write(torch::serialize::OutputArchive& archive, const std::string& prefix) const {
    torch::serialize::OutputArchive a, b, c;
    phi->save(a);
    psi->save(b);
    psi_target->save(c);
    archive.write(prefix + "phi", a);
    archive.write(prefix + "psi", b);
    archive.write(prefix + "psi_target", c);
    nn::WriteAdam(archive, prefix + "optimizer", *optimizer);
  }

  void Read(torch::serialize::InputArchive& archive, const std::string& prefix) {
    torch::serialize::InputArchive a, b, c;
    archive.read(prefix + "phi", a);
    archive.read(prefix + "psi", b);
    archive.read(prefix + "psi_target", c);
    phi->load(a);
    psi->load(b);
    psi_target->load(c);
    nn::ReadAdam(archive, prefix + "optimizer", *optimizer);
  }

  nn::Mlp phi;
  nn::Mlp psi;
  nn::Mlp psi_target;
  std::unique_ptr<torch::optim::Adam> optimizer;
};

torch::Tensor Alive(const TransitionBatch& batch) {
  torch::Tensor alive = torch::ones({batch.size}, torch::kFloat32);
  if (batch.terminated != nullptr) {
    float* a = alive.data_ptr<float>();
    for (int64_t i = 0; i < batch.size; ++i) a[i] = batch.terminated[i] ? 0.0f : 1.0f;
  }
  return alive;
}

uint64_t Mix(uint64_t h, uint64_t x) {
  uint64_t s = h ^ (x + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2));
  return Rng::SplitMix64(s);
}

}  // namespace

struct SfNovelty::Impl {
  Impl(const env::Scenario& scenario, const ScorerConfig& config, const SfConfig& sf, NoveltyReads reads)
      : n(scenario.num_agents()),
        config(config),
        sf(sf),
        encoder(scenario),
        tag(absl::StrCat(kMagic, " ", scenario.name(), " ", scenario.map().width(), "x", scenario.map().height(),
                         " n=", n, " credit=", config.credit,
                         " permutation=", PermutationName(config.permutation))) {
    if (reads == NoveltyReads::kLocal) {
      local.emplace(encoder.local_state_dim(config.permutation == Permutation::kOff), sf, config.seed);
    } else if (reads != NoveltyReads::kNothing) {
      joint.emplace(encoder.state_dim(), sf, config.seed);
    }
  }

  // N_ep including this visit; counted unless dry_run.
  uint32_t Visit(uint64_t key, bool dry_run) {
    auto it = visits.find(key);
    uint32_t count = it != visits.end() ? it->second : 0;
    if (it == visits.end()) {
      auto old = previous_visits.find(key);
      if (old != previous_visits.end()) count = old->second;
    }
    if (!dry_run) visits[key] = count + 1;
    return count + 1;
  }

  void EndRequest(bool dry_run) {
    if (dry_run) return;
    ++requests;
    if (requests % sf.target_update == 0) {
      if (joint) joint->SyncTarget();
      if (local) local->SyncTarget();
    }
    if (requests % kGenerationRequests == 0) {
      previous_visits = std::move(visits);
      visits.clear();
    }
  }

  // One joint state in agent order as a [1][D] input (the *ForTest probes).
  torch::Tensor EncodeForTest(const int32_t* state) const {
    std::vector<float> x(encoder.state_dim());
    int order[env::kMaxAgents];
    for (int a = 0; a < n; ++a) order[a] = a;
    encoder.EncodeState(state, order, x.data());
    return torch::tensor(x).unsqueeze(0);
  }
  // `deferred` (deterministic scoring, LearnedNovelty::Deferred): score with
  // psi as it is and append the training step to it.
  void ComputeJoint(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out,
                    LearnedNovelty::Deferred* deferred);
  void ComputeLocal(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out,
                    LearnedNovelty::Deferred* deferred);

  const int n;
  const ScorerConfig config;
  const SfConfig sf;
  const JointInputEncoder encoder;
  const std::string tag;

  std::optional<SfModel> joint;
  std::optional<SfModel> local;
  int64_t requests = 0;
  absl::flat_hash_map<uint64_t, uint32_t> visits;
  absl::flat_hash_map<uint64_t, uint32_t> previous_visits;
};

void SfNovelty::Impl::ComputeJoint(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out,
                                   LearnedNovelty::Deferred* deferred) {
  const int64_t N = batch.size, D = encoder.state_dim(), K = batch.state_size;
  const bool imca = out.contributions != nullptr;
  // Rows: S_t [N], S_{t+1} [N], then (imca) S_t with only agent a moved [N][n].
  const int64_t rows = N * (2 + (imca ? n : 0));
  Clock::time_point lap = Clock::now();
  torch::Tensor inputs = torch::empty({rows, D}, torch::kFloat32);
  float* x = inputs.data_ptr<float>();
  int order[env::kMaxAgents];
  for (int a = 0; a < n; ++a) order[a] = a;
  std::vector<int32_t> moved(K);
  for (int64_t i = 0; i < N; ++i) {
    const int32_t* now = batch.states + i * K;
    const int32_t* next = batch.next_states + i * K;
    encoder.EncodeState(now, order, x + i * D);
    encoder.EncodeState(next, order, x + (N + i) * D);
    if (!imca) continue;
    for (int a = 0; a < n; ++a) {
      std::copy(now, now + K, moved.begin());
      moved[env::AgentIndex(a)] = next[env::AgentIndex(a)];
      // Another agent may stand on that cell at t: the encoding is still
      // defined (two one-hots coincide), as in the paper's eq. 11.
      encoder.EncodeState(moved.data(), order, x + (2 * N + i * n + a) * D);
    }
  }
  AddPart(out, ScorePhase::kEncode, Lap(lap));
  // The counterfactual rows ride in the same pass (counted as novelty).
  SfModel& model = *joint;
  const torch::Tensor psi = model.Psi(inputs);
  const torch::Tensor psi_now = psi.narrow(0, 0, N);
  const torch::Tensor global = (psi.narrow(0, N, N) - psi_now).pow(2).sum(1).contiguous();
  const float* g = global.data_ptr<float>();
  torch::Tensor d;
  if (imca) {
    d = (psi.narrow(0, 2 * N, N * n).view({N, n, -1}) - psi_now.unsqueeze(1)).pow(2).sum(2).contiguous();
  }
  for (int64_t i = 0; i < N; ++i) {
    out.joint[i] = g[i];
    if (!imca) continue;
    const float* da = d.data_ptr<float>() + i * n;
    const int32_t* next = batch.next_states + i * K;
    for (int a = 0; a < n; ++a) {
      out.contributions[i * n + a] = da[a];
      uint64_t key = Mix(Mix(Mix(batch.actor, static_cast<uint64_t>(batch.episode_ids[i])), a),
                         static_cast<uint64_t>(next[env::AgentIndex(a)]));
      const uint32_t visits = Visit(key, dry_run);
      out.agent_divisor[i * n + a] = std::sqrt(static_cast<double>(visits));
    }
  }
  if (deferred != nullptr) {
    // Copies: the views would keep the counterfactual rows alive too.
    deferred->push_back([this, x = inputs.narrow(0, 0, N).clone(), next = inputs.narrow(0, N, N).clone(),
                         alive = Alive(batch)] { joint->Train(x, next, alive, sf.gamma); });
  } else if (!dry_run) {
    lap = Clock::now();
    model.Train(inputs.narrow(0, 0, N), inputs.narrow(0, N, N), Alive(batch), sf.gamma);
    AddPart(out, ScorePhase::kTrain, Lap(lap));
  }
}

void SfNovelty::Impl::ComputeLocal(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out,
                                   LearnedNovelty::Deferred* deferred) {
  const bool with_id = config.permutation == Permutation::kOff;
  const int64_t N = batch.size, D = encoder.local_state_dim(with_id), K = batch.state_size;
  Clock::time_point lap = Clock::now();
  torch::Tensor inputs = torch::empty({2 * N * n, D}, torch::kFloat32);
  float* x = inputs.data_ptr<float>();
  for (int64_t i = 0; i < N; ++i) {
    for (int a = 0; a < n; ++a) {
      encoder.EncodeLocalState(batch.states + i * K, a, with_id, x + (i * n + a) * D);
      encoder.EncodeLocalState(batch.next_states + i * K, a, with_id, x + (N * n + i * n + a) * D);
    }
  }
  AddPart(out, ScorePhase::kEncode, Lap(lap));
  SfModel& model = *local;
  const torch::Tensor psi = model.Psi(inputs);
  const torch::Tensor novelty = (psi.narrow(0, N * n, N * n) - psi.narrow(0, 0, N * n)).pow(2).sum(1).contiguous();
  const float* nov = novelty.data_ptr<float>();
  std::copy(nov, nov + N * n, out.local);
  if (deferred != nullptr) {
    deferred->push_back([this, x = inputs.narrow(0, 0, N * n), next = inputs.narrow(0, N * n, N * n),
           alive = Alive(batch).repeat_interleave(n)] { local->Train(x, next, alive, sf.gamma); });
  } else if (!dry_run) {
    lap = Clock::now();
    const torch::Tensor alive = Alive(batch).repeat_interleave(n);
    model.Train(inputs.narrow(0, 0, N * n), inputs.narrow(0, N * n, N * n), alive, sf.gamma);
    AddPart(out, ScorePhase::kTrain, Lap(lap));
  }
}

absl::StatusOr<std::unique_ptr<SfNovelty>> SfNovelty::Create(const env::Scenario& scenario,
                                                           const ScorerConfig& config, const SfConfig& sf) {
  IMCA_RETURN_IF_ERROR(CheckNetwork("sf", sf.hidden, sf.learning_rate, sf.gamma));
  IMCA_ASSIGN_OR_RETURN(const NoveltyReads reads, CreditReads(config.credit));
  if (sf.features < 1) return absl::InvalidArgumentError("sf features must be >= 1");
  if (sf.target_update < 1) return absl::InvalidArgumentError("sf target update period must be >= 1");
  return std::unique_ptr<SfNovelty>(new SfNovelty(std::make_unique<Impl>(scenario, config, sf, reads), reads));
}

SfNovelty::SfNovelty(std::unique_ptr<Impl> impl, NoveltyReads reads)
    : LearnedNovelty("sf", impl->config.credit, reads, impl->config.deterministic), impl_(std::move(impl)) {}

void SfNovelty::EndRequest(bool dry_run) { impl_->EndRequest(dry_run); }
SfNovelty::~SfNovelty() = default;

void SfNovelty::ComputeJoint(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out,
                             Deferred* deferred) {
  impl_->ComputeJoint(batch, dry_run, out, deferred);
}

void SfNovelty::ComputeLocal(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out,
                             Deferred* deferred) {
  impl_->ComputeLocal(batch, dry_run, out, deferred);
}

void SfNovelty::FillStats(v1::RewardStats* stats) const {
  stats->set_model_updates(impl_->requests);
  stats->set_distinct_keys(static_cast<int64_t>(impl_->visits.size()));
}

absl::StatusOr<std::string> SfNovelty::Serialize() const {
  return nn::SerializeModels(impl_->tag, impl_->joint, impl_->local, "requests", impl_->requests);
}

absl::Status SfNovelty::Load(const std::string& path) {
  Impl& impl = *impl_;
  const bool with_id = impl.config.permutation == Permutation::kOff;
  const absl::Status loaded = nn::LoadModels<SfModel>(
      path, impl.tag, &impl.joint, &impl.local, [&] { return SfModel(impl.encoder.state_dim(), impl.sf, impl.config.seed); },
      [&] { return SfModel(impl.encoder.local_state_dim(with_id), impl.sf, impl.config.seed); }, "requests", &impl.requests);
  if (loaded.ok()) DropPending();
  return loaded;
}

absl::Status SfNovelty::SetLinearForTest(const std::string& net, int layer, const std::vector<float>& weight,
                                        const std::vector<float>& bias) {
  const bool is_local = net.rfind("local_", 0) == 0;
  std::optional<SfModel>& model = is_local ? impl_->local : impl_->joint;
  const std::string which = is_local ? net.substr(6) : net;
  if (!model || (which != "phi" && which != "psi")) {
    return absl::InvalidArgumentError(absl::StrCat("no net '", net, "' in this credit mode"));
  }
  IMCA_RETURN_IF_ERROR(nn::SetLinear(which == "phi" ? model->phi : model->psi, layer, weight, bias));
  model->SyncTarget();
  return absl::OkStatus();
}

std::vector<float> SfNovelty::PhiForTest(const int32_t* state) const {
  torch::NoGradGuard no_grad;
  const torch::Tensor y = impl_->joint->phi->forward(impl_->EncodeForTest(state)).squeeze(0).contiguous();
  return std::vector<float>(y.data_ptr<float>(), y.data_ptr<float>() + y.numel());
}

std::vector<float> SfNovelty::PsiForTest(const int32_t* state) const {
  const torch::Tensor y = impl_->joint->Psi(impl_->EncodeForTest(state)).squeeze(0).contiguous();
  return std::vector<float>(y.data_ptr<float>(), y.data_ptr<float>() + y.numel());
}

}  // namespace imca::reward
