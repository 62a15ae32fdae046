#include "reward_server/novelty/rnd_novelty.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <optional>

#include "absl/strings/str_cat.h"
#include "common/base/lap.h"
#include "common/base/rng.h"
#include "common/base/status_macros.h"
#include "common/nn/archive.h"
#include "common/nn/mlp.h"
#include "common/nn/running_moments.h"
#include "common/nn/torch_status.h"
#include "reward_server/novelty/counterfactual_mlp.h"
#include "reward_server/novelty/joint_input.h"
#include "reward_server/novelty/joint_key.h"

namespace imca::reward {
namespace {

constexpr char kMagic[] = "IMCA-RND-2";  // 2: moments as one [2 dim + 1] tensor each.
constexpr char kLegacyMagic[] = "IMCA-RND-1";  // Still read (Load).
constexpr double kEps = 1e-8;

std::vector<int64_t> Sizes(int64_t in, const RndConfig& config) {
  std::vector<int64_t> sizes = {in};
  for (int h : config.hidden) sizes.push_back(h);
  sizes.push_back(config.output);
  return sizes;
}

// A snapshot's moments; throws (LoadArchive's DATA_LOSS) if they are bad.
nn::RunningMoments MomentsFromTensor(const torch::Tensor& t, int64_t dim, const std::string& name) {
  absl::StatusOr<nn::RunningMoments> moments = nn::RunningMoments::FromTensor(t, dim, name);
  if (!moments.ok()) throw std::runtime_error(std::string(moments.status().message()));
  return *std::move(moments);
}

// One RND pair with its normalisers and the predictor's optimiser.
struct Model {
  // Target and predictor draw their initial weights from streams 1 and 2 of `seed`.
  Model(int64_t in, const RndConfig& config, uint64_t seed)
      : target(nn::MlpOptions(Sizes(in, config)).seed(nn::SubSeed(seed, 1))),
        predictor(nn::MlpOptions(Sizes(in, config)).seed(nn::SubSeed(seed, 2))),
        obs(in),
        ret(1),
        normalize(config.normalize) {
    for (auto& p : target->parameters()) p.set_requires_grad(false);
    optimizer = std::make_unique<torch::optim::Adam>(
        predictor->parameters(), torch::optim::AdamOptions(config.learning_rate));
  }

  torch::Tensor Normalize(const torch::Tensor& x) const {
    if (!normalize) return x;
    return ((x - obs.mean().to(torch::kFloat32)) / torch::sqrt(obs.var().to(torch::kFloat32) + kEps)).clamp(-5.0, 5.0);
  }

  // A forward pass of both nets over normalised rows: the raw novelty of
  // each row and each net's first-layer pre-activation (the counterfactuals
  // start from it).
  struct Pass {
    torch::Tensor novelty;               // [N]
    torch::Tensor h_target, h_predictor;  // [N][H]
  };
  Pass Novelty(const torch::Tensor& x) {
    torch::NoGradGuard no_grad;
    Pass pass;
    pass.h_target = target->layers()[0]->forward(x).contiguous();
    pass.h_predictor = predictor->layers()[0]->forward(x).contiguous();
    pass.novelty =
        (target->ForwardFrom(pass.h_target, 0) - predictor->ForwardFrom(pass.h_predictor, 0)).pow(2).mean(1);
    return pass;
  }

  // Novelty of every counterfactual row of the rows of `pass` without
  // building it. Row (i, s, u) is the taken row i with the action block of
  // slot s set to action u; the blocks start at `action_offset`, A columns
  // each, and `taken` [N][n] (int64) holds the slot actions of the rows.
  // Normalisation is per column, so a row differs from the taken one only in
  // that block, and the first layer's pre-activation is
  // h - W_s v(taken) + W_s v(u), with v(u) the normalised one-hot; the rest
  // of both nets runs in CounterfactualNovelties on `threads` threads.
  // `alongside`, if set, runs on this thread meanwhile (the predictor's
  // training step: the rows use a copy of the predictor's layers taken
  // before it, so they are the values without it). Returns [N][n][A].
  torch::Tensor CounterfactualNovelty(const Pass& pass, const torch::Tensor& taken, int64_t action_offset,
                                      int64_t n, int64_t A, int threads, const std::function<void()>& alongside) {
    // No gradients for what the rows read; the training step alongside runs
    // after this scope, with the caller's grad mode.
    std::optional<torch::NoGradGuard> no_grad(std::in_place);
    const int64_t N = pass.novelty.size(0);
    // v [n][A][A]: the normalised one-hot of action u in slot s's columns.
    torch::Tensor v = torch::eye(A, torch::kFloat32).unsqueeze(0).expand({n, A, A}).contiguous();
    if (normalize) {
      const auto cols = torch::indexing::Slice(action_offset, action_offset + n * A);
      const torch::Tensor mean = obs.mean().index({cols}).to(torch::kFloat32).view({n, 1, A});
      const torch::Tensor std = torch::sqrt(obs.var().index({cols}).to(torch::kFloat32) + kEps).view({n, 1, A});
      v = ((v - mean) / std).clamp(-5.0, 5.0);
    }
    // c [n][A][H]: the first layer's response to slot s taking action u; and
    // the views of the layers after it.
    auto response = [&](nn::Mlp& net) {
      const torch::Tensor& w = net->layers()[0]->weight;  // [H][D]
      return torch::matmul(v, w.narrow(1, action_offset, n * A).reshape({-1, n, A}).permute({1, 2, 0})).contiguous();
    };
    // With `copy`, the views are of copies kept in `copies` (the training
    // step alongside changes the predictor's in place).
    std::vector<torch::Tensor> copies;
    auto tail = [&copies](nn::Mlp& net, bool copy) {
      TORCH_CHECK(net->options().activation() == nn::Activation::kRelu && !net->options().layer_norm(),
                  "rnd counterfactuals need a plain ReLU network");
      MlpTail t;
      auto& layers = net->layers();
      for (size_t l = 1; l < layers.size(); ++l) {
        torch::Tensor weight = layers[l]->weight, bias = layers[l]->bias;
        TORCH_CHECK(weight.scalar_type() == torch::kFloat32 && bias.scalar_type() == torch::kFloat32,
                    "rnd counterfactuals need float32 layers");
        if (copy || !weight.is_contiguous() || !bias.is_contiguous()) {
          weight = copies.emplace_back(weight.clone(at::MemoryFormat::Contiguous));
          bias = copies.emplace_back(bias.clone(at::MemoryFormat::Contiguous));
        }
        t.layers.push_back({weight.data_ptr<float>(), bias.data_ptr<float>(), static_cast<int>(weight.size(0)),
                            static_cast<int>(weight.size(1))});
      }
      return t;
    };
    const torch::Tensor c_target = response(target), c_predictor = response(predictor);
    const torch::Tensor taken_rows = taken.contiguous(), taken_novelty = pass.novelty.contiguous();
    torch::Tensor out = torch::empty({N, n, A}, torch::kFloat32);
    const MlpTail target_tail = tail(target, false), predictor_tail = tail(predictor, bool{alongside});
    no_grad.reset();
    CounterfactualNovelties(target_tail, predictor_tail, N, static_cast<int>(n), static_cast<int>(A),
                            static_cast<int>(pass.h_target.size(1)), pass.h_target.data_ptr<float>(),
                            pass.h_predictor.data_ptr<float>(), c_target.data_ptr<float>(),
                            c_predictor.data_ptr<float>(), taken_rows.data_ptr<int64_t>(),
                            taken_novelty.data_ptr<float>(), out.data_ptr<float>(), threads, alongside);
    return out;
  }

  double RewardStd() const { return normalize ? std::sqrt(ret.scalar_var() + kEps) : 1.0; }

  void Train(const torch::Tensor& x) {
    optimizer->zero_grad();
    torch::Tensor loss;
    {
      torch::Tensor goal;
      {
        torch::NoGradGuard no_grad;
        goal = target->forward(x);
      }
      loss = (predictor->forward(x) - goal).pow(2).mean();
    }
    loss.backward();
    optimizer->step();
  }

  void Write(torch::serialize::OutputArchive& archive, const std::string& prefix) const {
    torch::serialize::OutputArchive t, p;
    target->save(t);
    predictor->save(p);
    archive.write(prefix + "target", t);
    archive.write(prefix + "predictor", p);
    nn::WriteAdam(archive, prefix + "optimizer", *optimizer);
    archive.write(prefix + "obs_moments", obs.ToTensor());
    archive.write(prefix + "ret_moments", ret.ToTensor());
  }

  void Read(torch::serialize::InputArchive& archive, const std::string& prefix) {
    torch::serialize::InputArchive t, p;
    archive.read(prefix + "target", t);
    archive.read(prefix + "predictor", p);
    target->load(t);
    predictor->load(p);
    nn::ReadAdam(archive, prefix + "optimizer", *optimizer);
    obs = ReadMoments(archive, prefix + "obs", obs.dim());
    ret = ReadMoments(archive, prefix + "ret", 1);
  }

  // "<name>_moments" ([2 dim + 1], IMCA-RND-2), or an IMCA-RND-1
  // snapshot's "<name>_mean", "<name>_var", "<name>_count".
  static nn::RunningMoments ReadMoments(torch::serialize::InputArchive& archive, const std::string& name,
                                        int64_t dim) {
    torch::Tensor moments;
    if (!archive.try_read(name + "_moments", moments)) {
      torch::Tensor mean, var, count;
      archive.read(name + "_mean", mean);
      archive.read(name + "_var", var);
      archive.read(name + "_count", count);
      moments = torch::cat({mean.to(torch::kFloat64).reshape({-1}), var.to(torch::kFloat64).reshape({-1}),
                            count.to(torch::kFloat64).reshape({1})});
    }
    return MomentsFromTensor(moments, dim, name + "_moments");
  }

  nn::Mlp target;
  nn::Mlp predictor;
  std::unique_ptr<torch::optim::Adam> optimizer;
  nn::RunningMoments obs;
  nn::RunningMoments ret;
  bool normalize;
};

// Puts a model's input and return moments back as they were when it was
// made (if given a model), when it goes out of scope.
class MomentsGuard {
 public:
  explicit MomentsGuard(Model* model) : model_(model) {
    if (model_ != nullptr) {
      obs_ = model_->obs;
      ret_ = model_->ret;
    }
  }
  ~MomentsGuard() {
    if (model_ != nullptr) {
      model_->obs = obs_;
      model_->ret = ret_;
    }
  }
  MomentsGuard(const MomentsGuard&) = delete;
  MomentsGuard& operator=(const MomentsGuard&) = delete;

 private:
  Model* const model_;
  nn::RunningMoments obs_, ret_;
};

// Discounted returns of novelties [T][E][k] along t, per (e, k) stream.
torch::Tensor StreamReturns(const torch::Tensor& novelty, int64_t T, int64_t E, int64_t k, double gamma) {
  auto n = novelty.reshape({T, E * k}).to(torch::kFloat64);
  std::vector<torch::Tensor> out;
  torch::Tensor running = torch::zeros({E * k}, torch::kFloat64);
  for (int64_t t = 0; t < T; ++t) {
    running = running * gamma + n[t];
    out.push_back(running);
  }
  return torch::stack(out).reshape({T * E * k, 1});
}

}  // namespace

struct RndNovelty::Impl {
  Impl(const env::Scenario& scenario, const ScorerConfig& config, const RndConfig& rnd, NoveltyReads reads)
      : n(scenario.num_agents()),
        num_actions(scenario.num_actions()),
        config(config),
        rnd(rnd),
        encoder(scenario),
        codec(scenario),
        tag(absl::StrCat(kMagic, " ", scenario.name(), " ", scenario.map().width(), "x",
                         scenario.map().height(), " n=", n, " A=", num_actions, " credit=",
                         config.credit, " permutation=", PermutationName(config.permutation))),
        rng(config.seed) {
    if (reads == NoveltyReads::kLocal) {
      local.emplace(encoder.local_dim(config.permutation == Permutation::kOff), rnd, config.seed);
    } else if (reads != NoveltyReads::kNothing) {
      joint.emplace(encoder.joint_dim(), rnd, config.seed);
    }
  }

  // `deferred` (deterministic scoring, LearnedNovelty::Deferred): score with
  // the models and moments as they are, and append the updates to it.
  void ComputeJoint(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out,
                    LearnedNovelty::Deferred* deferred);
  void ComputeLocal(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out,
                    LearnedNovelty::Deferred* deferred);
  void TrainJoint(const TransitionBatch& batch, const torch::Tensor& inputs);

  const int n;
  const int num_actions;
  const ScorerConfig config;
  const RndConfig rnd;
  const JointInputEncoder encoder;
  const JointKeyCodec codec;
  const std::string tag;

  Rng rng;
  std::optional<Model> joint;
  std::optional<Model> local;
  int64_t updates = 0;
};

void RndNovelty::Impl::ComputeJoint(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out,
                                    LearnedNovelty::Deferred* deferred) {
  const int64_t N = batch.size, D = encoder.joint_dim(), A = num_actions;
  const bool imca = out.contributions != nullptr;
  Clock::time_point lap = Clock::now();
  torch::Tensor inputs = torch::empty({N, D}, torch::kFloat32);
  float* x = inputs.data_ptr<float>();
  std::vector<int> orders(N * n);
  // slot_of[i*n + a]: agent a's slot in row i; taken[i][s]: the action in slot s.
  std::vector<int> slot_of(imca ? N * n : 0);
  torch::Tensor taken = imca ? torch::empty({N, n}, torch::kInt64) : torch::Tensor();
  const int64_t stride = batch.state_size;
  for (int64_t i = 0; i < N; ++i) {
    const int32_t* state = batch.states + i * stride;
    int* order = &orders[i * n];
    codec.SlotOrder(state, config.permutation == Permutation::kCanonical, order);
    encoder.EncodeJoint(state, batch.actions + i * n, order, x + i * D);
    if (!imca) continue;
    int64_t* t = taken.data_ptr<int64_t>() + i * n;
    for (int slot = 0; slot < n; ++slot) {
      slot_of[i * n + order[slot]] = slot;
      t[slot] = batch.actions[i * n + order[slot]];
    }
  }
  AddPart(out, ScorePhase::kEncode, Lap(lap));
  Model& model = *joint;
  // Deferring: the call's own moments are used, then put back, on every
  // path (Update replaces the moments' tensors, so the copies stay as they
  // were).
  const MomentsGuard moments(deferred != nullptr ? &model : nullptr);
  if (!dry_run && model.normalize) model.obs.Update(inputs);
  const torch::Tensor normalized = model.Normalize(inputs);
  const Model::Pass pass = model.Novelty(normalized);
  const torch::Tensor& novelty = pass.novelty;
  torch::Tensor returns;
  if (!dry_run && model.normalize) {
    returns = StreamReturns(novelty, batch.length, batch.num_envs, 1, rnd.gamma);
    model.ret.Update(returns);
  }
  const double std = model.RewardStd();
  const torch::Tensor scaled = (novelty / std).contiguous();
  const float* nov = scaled.data_ptr<float>();
  // Counterfactual novelties [N][n slots][A], scaled like the bonus (docs/credit.md).
  // Outside a dry run the predictor's training step runs alongside the rows
  // (it needs none of them, and they read a copy of the predictor taken
  // before it); the counterfactual phase is then the time the rows add past
  // that step.
  double train_seconds = 0;
  std::function<void()> train;
  if (!dry_run && deferred == nullptr) {
    train = [&] {
      Clock::time_point start = Clock::now();
      TrainJoint(batch, inputs);
      train_seconds = Lap(start);
      AddPart(out, ScorePhase::kTrain, train_seconds);
    };
  }
  torch::Tensor cf;
  if (imca) {
    lap = Clock::now();
    cf = (model.CounterfactualNovelty(pass, taken, encoder.state_dim(), n, A, rnd.counterfactual_threads, train) /
          std)
             .contiguous();
    AddPart(out, ScorePhase::kCounterfactual, std::max(0.0, Lap(lap) - train_seconds));
  }
  for (int64_t i = 0; i < N; ++i) {
    out.joint[i] = nov[i];
    if (!imca) continue;
    for (int a = 0; a < n; ++a) {
      double baseline = 0;
      const float* probs = batch.action_probs + (i * n + a) * A;
      const float* counterfactual = cf.data_ptr<float>() + (i * n + slot_of[i * n + a]) * A;
      for (int u = 0; u < A; ++u) baseline += probs[u] * counterfactual[u];
      out.contributions[i * n + a] = static_cast<float>(nov[i] - baseline);
    }
  }
  if (train && !imca) train();
  if (deferred != nullptr) {
    // The step reads states and actions under permutation random: kept with it.
    const bool permuted = config.permutation == Permutation::kRandom;
    std::vector<int32_t> states(permuted ? batch.states : nullptr, permuted ? batch.states + N * stride : nullptr);
    std::vector<int32_t> actions(permuted ? batch.actions : nullptr, permuted ? batch.actions + N * n : nullptr);
    deferred->push_back([this, inputs, returns, states = std::move(states), actions = std::move(actions), N, stride] {
      Model& model = *joint;
      if (model.normalize) {
        model.obs.Update(inputs);
        model.ret.Update(returns);
      }
      TransitionBatch kept;
      kept.size = N;
      kept.state_size = stride;
      kept.states = states.data();
      kept.actions = actions.data();
      TrainJoint(kept, inputs);
    });
  }
}

void RndNovelty::Impl::TrainJoint(const TransitionBatch& batch, const torch::Tensor& taken) {
  Model& model = *joint;
  const int64_t N = batch.size, D = encoder.joint_dim();
  torch::Tensor train = taken;
  if (config.permutation == Permutation::kRandom) {
    // The paper's 4.3: learn the pair under a random permutation of the agents.
    train = torch::empty({N, D}, torch::kFloat32);
    float* x = train.data_ptr<float>();
    int order[env::kMaxAgents];
    for (int64_t i = 0; i < N; ++i) {
      for (int a = 0; a < n; ++a) order[a] = a;
      for (int slot = n - 1; slot > 0; --slot) std::swap(order[slot], order[rng.Uniform(slot + 1)]);
      encoder.EncodeJoint(batch.states + i * batch.state_size, batch.actions + i * n, order, x + i * D);
    }
  }
  const int64_t keep = std::max<int64_t>(1, static_cast<int64_t>(std::lround(rnd.update_proportion * N)));
  if (keep < N) {
    std::vector<int64_t> idx(N);
    for (int64_t i = 0; i < N; ++i) idx[i] = i;
    for (int64_t i = 0; i < keep; ++i) std::swap(idx[i], idx[i + rng.Uniform(static_cast<uint32_t>(N - i))]);
    idx.resize(keep);
    train = train.index_select(0, torch::tensor(idx, torch::kInt64));
  }
  model.Train(model.Normalize(train));
  ++updates;
}

void RndNovelty::Impl::ComputeLocal(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out,
                                    LearnedNovelty::Deferred* deferred) {
  const bool with_id = config.permutation == Permutation::kOff;
  const int64_t N = batch.size, D = encoder.local_dim(with_id);
  Clock::time_point lap = Clock::now();
  torch::Tensor inputs = torch::empty({N * n, D}, torch::kFloat32);
  float* x = inputs.data_ptr<float>();
  for (int64_t i = 0; i < N; ++i) {
    for (int a = 0; a < n; ++a) {
      encoder.EncodeLocal(batch.states + i * batch.state_size, a, batch.actions[i * n + a], with_id,
                          x + (i * n + a) * D);
    }
  }
  AddPart(out, ScorePhase::kEncode, Lap(lap));
  Model& model = *local;
  const MomentsGuard moments(deferred != nullptr ? &model : nullptr);  // As ComputeJoint's.
  if (!dry_run && model.normalize) model.obs.Update(inputs);
  const torch::Tensor novelty = model.Novelty(model.Normalize(inputs)).novelty;
  torch::Tensor returns;
  if (!dry_run && model.normalize) {
    returns = StreamReturns(novelty, batch.length, batch.num_envs, n, rnd.gamma);
    model.ret.Update(returns);
  }
  const torch::Tensor scaled = (novelty / model.RewardStd()).contiguous();
  const float* nov = scaled.data_ptr<float>();
  std::copy(nov, nov + N * n, out.local);
  if (deferred != nullptr) {
    deferred->push_back([this, inputs, returns] {
      Model& model = *local;
      if (model.normalize) {
        model.obs.Update(inputs);
        model.ret.Update(returns);
      }
      model.Train(model.Normalize(inputs));
      ++updates;
    });
  } else if (!dry_run) {
    lap = Clock::now();
    model.Train(model.Normalize(inputs));
    ++updates;
    AddPart(out, ScorePhase::kTrain, Lap(lap));
  }
}

absl::StatusOr<std::unique_ptr<RndNovelty>> RndNovelty::Create(const env::Scenario& scenario,
                                                             const ScorerConfig& config, const RndConfig& rnd) {
  IMCA_RETURN_IF_ERROR(CheckNetwork("rnd", rnd.hidden, rnd.learning_rate, rnd.gamma));
  IMCA_ASSIGN_OR_RETURN(const NoveltyReads reads, CreditReads(config.credit));
  if (rnd.output < 1) return absl::InvalidArgumentError("rnd output size must be >= 1");
  if (rnd.counterfactual_threads < 1 || rnd.counterfactual_threads > 64) {
    return absl::InvalidArgumentError("rnd counterfactual threads must be in [1, 64]");
  }
  if (!(rnd.update_proportion > 0 && rnd.update_proportion <= 1)) {
    return absl::InvalidArgumentError("rnd update proportion must be in (0, 1]");
  }
  return std::unique_ptr<RndNovelty>(new RndNovelty(std::make_unique<Impl>(scenario, config, rnd, reads), reads));
}

RndNovelty::RndNovelty(std::unique_ptr<Impl> impl, NoveltyReads reads)
    : LearnedNovelty("rnd", impl->config.credit, reads, impl->config.deterministic), impl_(std::move(impl)) {}
RndNovelty::~RndNovelty() = default;

void RndNovelty::ComputeJoint(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out,
                              Deferred* deferred) {
  impl_->ComputeJoint(batch, dry_run, out, deferred);
}

void RndNovelty::ComputeLocal(const TransitionBatch& batch, bool dry_run, const NoveltyOutput& out,
                              Deferred* deferred) {
  impl_->ComputeLocal(batch, dry_run, out, deferred);
}

void RndNovelty::FillStats(v1::RewardStats* stats) const {
  stats->set_model_updates(impl_->updates);
}

absl::StatusOr<std::string> RndNovelty::Serialize() const {
  return nn::SerializeModels(impl_->tag, impl_->joint, impl_->local, "updates", impl_->updates);
}

absl::Status RndNovelty::Load(const std::string& path) {
  Impl& impl = *impl_;
  const bool with_id = impl.config.permutation == Permutation::kOff;
  const auto load = [&](const std::string& tag) {
    return nn::LoadModels<Model>(
        path, tag, &impl.joint, &impl.local,
        [&] { return Model(impl.encoder.joint_dim(), impl.rnd, impl.config.seed); },
        [&] { return Model(impl.encoder.local_dim(with_id), impl.rnd, impl.config.seed); }, "updates",
        &impl.updates);
  };
  absl::Status loaded = load(impl.tag);
  // A snapshot of a run started before this version resumes too.
  if (absl::IsFailedPrecondition(loaded)) {
    const absl::Status legacy = load(kLegacyMagic + impl.tag.substr(std::string(kMagic).size()));
    if (!absl::IsFailedPrecondition(legacy)) loaded = legacy;
  }
  if (loaded.ok()) DropPending();
  return loaded;
}

absl::Status RndNovelty::SetLinearForTest(const std::string& net, int layer, const std::vector<float>& weight,
                                         const std::vector<float>& bias) {
  const bool is_local = net.rfind("local_", 0) == 0;
  std::optional<Model>& model = is_local ? impl_->local : impl_->joint;
  const std::string which = is_local ? net.substr(6) : net;
  if (!model || (which != "target" && which != "predictor")) {
    return absl::InvalidArgumentError(absl::StrCat("no net '", net, "' in this credit mode"));
  }
  return nn::SetLinear(which == "target" ? model->target : model->predictor, layer, weight, bias);
}

}  // namespace imca::reward
