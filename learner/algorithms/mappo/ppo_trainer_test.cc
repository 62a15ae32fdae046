#include "learner/algorithms/mappo/ppo_trainer.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <map>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include <torch/torch.h>

#include "common/protocol/policy_mlp.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "learner/algorithms/mappo/ppo_losses.h"

namespace imca::learner {


namespace {

using ::testing::HasSubstr;

constexpr int kContexts = 2;
// The bandit: in context 0 action 1 pays 1, in context 1 action 3 does.
constexpr int kBanditActions = 5;
constexpr int kRightAction[kContexts] = {1, 3};

PpoConfig SmallConfig() {
  PpoConfig config;
  config.hidden = 16;
  config.seed = 7;
  config.threads = 1;
  return config;
}

std::unique_ptr<PpoTrainer> MakeTrainer(const PpoConfig& config, int obs_dim = kContexts,
                                        int critic_dim = kContexts,
                                        int num_actions = kBanditActions) {
  auto trainer = PpoTrainer::Create(config, obs_dim, critic_dim, num_actions);
  EXPECT_TRUE(trainer.ok()) << trainer.status();
  return trainer.ok() ? std::move(trainer).value() : nullptr;
}

std::vector<float> OneHot(int context) {
  std::vector<float> x(kContexts, 0.0f);
  x[context] = 1.0f;
  return x;
}

// LayerNorm of x with the tensors "<prefix>.weight" / "<prefix>.bias".
void LayerNorm(const std::map<std::string, const v1::NamedTensor*>& by_name,
               const std::string& prefix, std::vector<double>& x) {
  const v1::NamedTensor& g = *by_name.at(prefix + ".weight");
  const v1::NamedTensor& b = *by_name.at(prefix + ".bias");
  double mean = 0, var = 0;
  for (double v : x) mean += v / x.size();
  for (double v : x) var += (v - mean) * (v - mean) / x.size();
  for (size_t i = 0; i < x.size(); ++i) {
    x[i] = (x[i] - mean) / std::sqrt(var + 1e-5) * g.data(i) + b.data(i);
  }
}

// An independent evaluator of an exported MLP_TANH or
// MLP_TANH_LAYERNORM policy: tanh (and LayerNorm) after every layer but
// the last, softmax on the last; the input's LayerNorm where the policy has
// one. Double precision.
std::vector<double> Probabilities(const v1::Policy& policy, const std::vector<float>& obs) {
  std::map<std::string, const v1::NamedTensor*> by_name;
  for (const v1::NamedTensor& t : policy.tensors()) by_name[t.name()] = &t;
  const bool layer_norm = policy.architecture() == v1::Policy::MLP_TANH_LAYERNORM;
  std::vector<double> x(obs.begin(), obs.end());
  if (layer_norm && by_name.count("policy.input_norm.weight") > 0) LayerNorm(by_name, "policy.input_norm", x);
  int layers = 0;
  while (by_name.count("policy." + std::to_string(layers) + ".weight") > 0) ++layers;
  for (int l = 0; l < layers; ++l) {
    const v1::NamedTensor& w = *by_name.at("policy." + std::to_string(l) + ".weight");
    const v1::NamedTensor& b = *by_name.at("policy." + std::to_string(l) + ".bias");
    const int64_t rows = w.shape(0), cols = w.shape(1);
    std::vector<double> y(rows);
    for (int64_t r = 0; r < rows; ++r) {
      double sum = b.data(r);
      for (int64_t c = 0; c < cols; ++c) sum += w.data(r * cols + c) * x[c];
      y[r] = (l + 1 < layers) ? std::tanh(sum) : sum;
    }
    x = std::move(y);
    if (layer_norm && l + 1 < layers) LayerNorm(by_name, "policy." + std::to_string(l) + ".norm", x);
  }
  const double max = *std::max_element(x.begin(), x.end());
  double total = 0;
  for (double& v : x) total += (v = std::exp(v - max));
  for (double& v : x) v /= total;
  return x;
}

std::vector<float> AllWeights(const v1::Policy& policy) {
  std::vector<float> all;
  for (const v1::NamedTensor& t : policy.tensors())
    all.insert(all.end(), t.data().begin(), t.data().end());
  return all;
}

// Values of the two one-hot critic inputs, as {ext0, ext1, int0, int1}.
std::vector<float> ContextValues(PpoTrainer& trainer) {
  std::vector<float> inputs = OneHot(0);
  const std::vector<float> second = OneHot(1);
  inputs.insert(inputs.end(), second.begin(), second.end());
  std::vector<float> v_ext(kContexts), v_int(kContexts);
  EXPECT_TRUE(trainer.Values(inputs.data(), kContexts, v_ext.data(), v_int.data()).ok());
  return {v_ext[0], v_ext[1], v_int[0], v_int[1]};
}

// A batch over alternating contexts with actions drawn from the trainer's
// current policy; the behaviour log-probs are that policy's.
PpoBatch BanditBatch(PpoTrainer& trainer, int size, std::mt19937& rng) {
  const v1::Policy policy = trainer.ExportPolicy(0);
  const std::vector<float> values = ContextValues(trainer);
  PpoBatch batch;
  batch.size = size;
  for (int i = 0; i < size; ++i) {
    const int context = i % kContexts;
    const std::vector<float> x = OneHot(context);
    const std::vector<double> p = Probabilities(policy, x);
    const int action = std::discrete_distribution<int>(p.begin(), p.end())(rng);
    const float reward = action == kRightAction[context] ? 1.0f : 0.0f;
    batch.obs.insert(batch.obs.end(), x.begin(), x.end());
    batch.critic_inputs.insert(batch.critic_inputs.end(), x.begin(), x.end());
    batch.actions.push_back(action);
    batch.behaviour_log_probs.push_back(static_cast<float>(std::log(p[action])));
    batch.advantages.push_back(reward - values[context]);
    batch.returns_ext.push_back(reward);
    batch.returns_int.push_back(0.0f);
  }
  return batch;
}

// A batch whose returns depend only on the context.
PpoBatch ConstantReturnBatch(int size, const float (&ext)[kContexts],
                             const float (&intr)[kContexts]) {
  PpoBatch batch;
  batch.size = size;
  for (int i = 0; i < size; ++i) {
    const int context = i % kContexts;
    const std::vector<float> x = OneHot(context);
    batch.obs.insert(batch.obs.end(), x.begin(), x.end());
    batch.critic_inputs.insert(batch.critic_inputs.end(), x.begin(), x.end());
    batch.actions.push_back(0);
    batch.behaviour_log_probs.push_back(std::log(1.0f / kBanditActions));
    batch.advantages.push_back(i % 3 == 0 ? 1.0f : -0.5f);
    batch.returns_ext.push_back(ext[context]);
    batch.returns_int.push_back(intr[context]);
  }
  return batch;
}

std::string TempPath(const std::string& name) { return ::testing::TempDir() + "/" + name; }

TEST(PpoTrainerTest, CreateRejectsBadSizesAndConfig) {
  const PpoConfig good = SmallConfig();
  EXPECT_TRUE(PpoTrainer::Create(good, 3, 4, 5).ok());
  for (const auto& [obs, critic, actions] :
       std::vector<std::tuple<int, int, int>>{{0, 4, 5}, {3, 0, 5}, {3, 4, 0}, {-1, 4, 5}}) {
    const auto t = PpoTrainer::Create(good, obs, critic, actions);
    EXPECT_EQ(t.status().code(), absl::StatusCode::kInvalidArgument)
        << obs << " " << critic << " " << actions;
  }
  std::vector<PpoConfig> bad(9, good);
  bad[0].hidden = 0;
  bad[1].learning_rate = 0;
  bad[2].adam_eps = -1;
  bad[3].clip = 0;
  bad[4].epochs = 0;
  bad[5].minibatches = 0;
  bad[6].threads = 0;
  bad[7].max_grad_norm = 0;
  bad[8].entropy_coef = -0.1;
  for (size_t i = 0; i < bad.size(); ++i) {
    EXPECT_EQ(PpoTrainer::Create(bad[i], 3, 4, 5).status().code(),
              absl::StatusCode::kInvalidArgument)
        << "config " << i;
  }
}

TEST(PpoTrainerTest, ExportPolicyHasNamesShapesAndInit) {
  PpoConfig config = SmallConfig();
  config.hidden = 8;
  auto trainer = MakeTrainer(config, /*obs_dim=*/3, /*critic_dim=*/6, /*num_actions=*/4);
  ASSERT_NE(trainer, nullptr);
  EXPECT_EQ(trainer->obs_dim(), 3);
  EXPECT_EQ(trainer->critic_dim(), 6);
  EXPECT_EQ(trainer->num_actions(), 4);
  const v1::Policy policy = trainer->ExportPolicy(42);
  EXPECT_EQ(policy.version(), 42);
  EXPECT_EQ(policy.architecture(), v1::Policy::MLP_TANH);
  EXPECT_EQ(policy.obs_dim(), 3);
  EXPECT_EQ(policy.num_actions(), 4);
  const std::vector<std::pair<std::string, std::vector<int64_t>>> expected = {
      {"policy.0.weight", {8, 3}}, {"policy.0.bias", {8}},      {"policy.1.weight", {8, 8}},
      {"policy.1.bias", {8}},      {"policy.2.weight", {4, 8}}, {"policy.2.bias", {4}}};
  ASSERT_EQ(policy.tensors_size(), static_cast<int>(expected.size()));
  for (size_t i = 0; i < expected.size(); ++i) {
    const v1::NamedTensor& t = policy.tensors(i);
    EXPECT_EQ(t.name(), expected[i].first);
    EXPECT_EQ(std::vector<int64_t>(t.shape().begin(), t.shape().end()), expected[i].second);
    int64_t n = 1;
    for (int64_t d : expected[i].second) n *= d;
    EXPECT_EQ(t.data_size(), n) << t.name();
    if (expected[i].second.size() == 1) {
      for (float b : t.data()) EXPECT_EQ(b, 0.0f) << t.name();
    }
  }
  // Orthogonal init, row-major [out, in]: layer 0 ([8, 3], gain sqrt 2) has
  // orthogonal columns, W^T W = 2 I; layer 2 ([4, 8], gain 0.01) has
  // orthogonal rows, W W^T = 1e-4 I.
  const auto& w0 = policy.tensors(0).data();
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) {
      double dot = 0;
      for (int r = 0; r < 8; ++r) dot += w0[r * 3 + a] * w0[r * 3 + b];
      EXPECT_NEAR(dot, a == b ? 2.0 : 0.0, 1e-5) << a << "," << b;
    }
  }
  const auto& w2 = policy.tensors(4).data();
  for (int a = 0; a < 4; ++a) {
    for (int b = 0; b < 4; ++b) {
      double dot = 0;
      for (int c = 0; c < 8; ++c) dot += w2[a * 8 + c] * w2[b * 8 + c];
      EXPECT_NEAR(dot, a == b ? 1e-4 : 0.0, 1e-9) << a << "," << b;
    }
  }
  // Hence the initial policy is close to uniform.
  for (double p : Probabilities(policy, {0.3f, -1.0f, 2.0f})) EXPECT_NEAR(p, 0.25, 0.01);
}

TEST(PpoTrainerTest, SameSeedSameWeights) {
  auto a = MakeTrainer(SmallConfig());
  auto b = MakeTrainer(SmallConfig());
  PpoConfig other = SmallConfig();
  other.seed = 8;
  auto c = MakeTrainer(other);
  ASSERT_TRUE(a && b && c);
  EXPECT_EQ(AllWeights(a->ExportPolicy(0)), AllWeights(b->ExportPolicy(0)));
  EXPECT_NE(AllWeights(a->ExportPolicy(0)), AllWeights(c->ExportPolicy(0)));
}

TEST(PpoTrainerTest, ConcurrentCriticGivesTheSameUpdateAsOneThread) {
  for (const bool separate : {true, false}) {
    PpoConfig config = SmallConfig();
    config.learning_rate = 3e-3;
    config.separate_optimizers = separate;
    config.concurrent_critic = true;
    auto concurrent = MakeTrainer(config);
    config.concurrent_critic = false;
    auto sequential = MakeTrainer(config);
    ASSERT_TRUE(concurrent && sequential);
    std::mt19937 rng_a(5), rng_b(5);
    for (int i = 0; i < 4; ++i) {
      const auto a = concurrent->Train(BanditBatch(*concurrent, 64, rng_a));
      const auto b = sequential->Train(BanditBatch(*sequential, 64, rng_b));
      ASSERT_TRUE(a.ok() && b.ok());
      EXPECT_EQ(a->value_loss, b->value_loss) << "separate " << separate << ", iteration " << i;
      EXPECT_EQ(a->grad_norm, b->grad_norm) << "separate " << separate << ", iteration " << i;
    }
    EXPECT_EQ(AllWeights(concurrent->ExportPolicy(0)), AllWeights(sequential->ExportPolicy(0)))
        << "separate " << separate;
    EXPECT_EQ(ContextValues(*concurrent), ContextValues(*sequential)) << "separate " << separate;
  }
}

TEST(PpoTrainerTest, ValuesApproachConstantReturns) {
  auto trainer = MakeTrainer(SmallConfig());
  ASSERT_NE(trainer, nullptr);
  const PpoBatch batch = ConstantReturnBatch(64, {100.0f, 100.0f}, {-3.0f, -3.0f});
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(trainer->Train(batch).ok());
  const std::vector<float> v = ContextValues(*trainer);
  EXPECT_NEAR(v[0], 100.0f, 0.5f);
  EXPECT_NEAR(v[1], 100.0f, 0.5f);
  EXPECT_NEAR(v[2], -3.0f, 0.5f);
  EXPECT_NEAR(v[3], -3.0f, 0.5f);
}

// EDTI's third head learns the interaction returns on its own normaliser, and
// a checkpoint carries it.
TEST(PpoTrainerTest, ThirdHeadLearnsTheInteractionReturnsAndRoundTrips) {
  PpoConfig config = SmallConfig();
  config.learning_rate = 3e-3;
  config.max_grad_norm = 10;
  config.value_heads = 3;
  auto trainer = MakeTrainer(config);
  ASSERT_NE(trainer, nullptr);
  PpoBatch batch = ConstantReturnBatch(64, {100.0f, 50.0f}, {1.0f, 3.0f});
  for (int i = 0; i < batch.size; ++i) batch.returns_voi.push_back(i % kContexts == 0 ? 20.0f : -4.0f);
  for (int i = 0; i < 30; ++i) ASSERT_TRUE(trainer->Train(batch).ok());
  std::vector<float> inputs = OneHot(0);
  const std::vector<float> second = OneHot(1);
  inputs.insert(inputs.end(), second.begin(), second.end());
  std::vector<float> v_ext(kContexts), v_int(kContexts), v_voi(kContexts);
  ASSERT_TRUE(trainer->Values(inputs.data(), kContexts, v_ext.data(), v_int.data(), v_voi.data()).ok());
  EXPECT_NEAR(v_ext[0], 100.0f, 2.0f);
  EXPECT_NEAR(v_int[1], 3.0f, 0.1f);
  EXPECT_NEAR(v_voi[0], 20.0f, 0.5f);
  EXPECT_NEAR(v_voi[1], -4.0f, 0.5f);
  // The batch must carry the third head's returns.
  PpoBatch missing = batch;
  missing.returns_voi.pop_back();
  EXPECT_THAT(std::string(trainer->Train(missing).status().message()), HasSubstr("returns_voi"));

  const std::string path = TempPath("ppo_trainer_test_three_heads.pt");
  ASSERT_TRUE(trainer->Save(path).ok());
  auto restored = MakeTrainer(config);
  ASSERT_NE(restored, nullptr);
  ASSERT_TRUE(restored->Load(path).ok());
  std::vector<float> r_ext(kContexts), r_int(kContexts), r_voi(kContexts);
  ASSERT_TRUE(restored->Values(inputs.data(), kContexts, r_ext.data(), r_int.data(), r_voi.data()).ok());
  EXPECT_EQ(r_voi, v_voi);
  std::remove(path.c_str());
}

TEST(PpoTrainerTest, ValuesLearnContextDependentReturns) {
  // Returns 100 / 50 (ext) and 1 / 3 (int): the normalised targets are about
  // +-1, so the critic itself must separate the contexts.
  PpoConfig config = SmallConfig();
  config.learning_rate = 3e-3;
  config.max_grad_norm = 10;
  auto trainer = MakeTrainer(config);
  ASSERT_NE(trainer, nullptr);
  const PpoBatch batch = ConstantReturnBatch(64, {100.0f, 50.0f}, {1.0f, 3.0f});
  for (int i = 0; i < 30; ++i) ASSERT_TRUE(trainer->Train(batch).ok());
  const std::vector<float> v = ContextValues(*trainer);
  EXPECT_NEAR(v[0], 100.0f, 2.0f);
  EXPECT_NEAR(v[1], 50.0f, 2.0f);
  EXPECT_NEAR(v[2], 1.0f, 0.1f);
  EXPECT_NEAR(v[3], 3.0f, 0.1f);
}

TEST(PpoTrainerTest, LearnsContextualBandit) {
  PpoConfig config = SmallConfig();
  config.learning_rate = 3e-3;
  auto trainer = MakeTrainer(config);
  ASSERT_NE(trainer, nullptr);
  std::mt19937 rng(123);
  PpoStats stats;
  for (int iteration = 0; iteration < 40; ++iteration) {
    const auto result = trainer->Train(BanditBatch(*trainer, 256, rng));
    ASSERT_TRUE(result.ok()) << result.status();
    stats = *result;
  }
  const v1::Policy policy = trainer->ExportPolicy(1);
  for (int context = 0; context < kContexts; ++context) {
    const std::vector<double> p = Probabilities(policy, OneHot(context));
    EXPECT_GT(p[kRightAction[context]], 0.9) << "context " << context;
  }
  EXPECT_TRUE(std::isfinite(stats.policy_loss));
  EXPECT_GT(stats.entropy, 0.0);
  EXPECT_LT(stats.entropy, std::log(kBanditActions));
  EXPECT_GE(stats.approx_kl, 0.0);
  EXPECT_GT(stats.grad_norm, 0.0);
}

TEST(ClippedSurrogateTest, NoGradientOutsideTheClipRange) {
  // ratio:      2    1.1   0.5   0.5   2
  // advantage:  1    1     1    -1    -2
  // min term:  1.2  1.1   0.5  -0.8  -4     (clipped, -, -, clipped, -)
  const torch::Tensor behaviour = torch::zeros({5});
  const torch::Tensor log_probs = torch::tensor({std::log(2.0f), std::log(1.1f), std::log(0.5f),
                                                 std::log(0.5f), std::log(2.0f)})
                                      .requires_grad_(true);
  const torch::Tensor advantages = torch::tensor({1.0f, 1.0f, 1.0f, -1.0f, -2.0f});
  const torch::Tensor loss =
      internal::ClippedSurrogateLoss(log_probs, behaviour, advantages, /*clip=*/0.2);
  EXPECT_NEAR(loss.item<float>(), -(1.2 + 1.1 + 0.5 - 0.8 - 4.0) / 5, 1e-6);
  loss.backward();
  // d loss / d log_prob_i = -ratio_i * A_i / 5 where unclipped, else 0.
  const std::vector<float> expected = {0.0f, -1.1f / 5, -0.5f / 5, 0.0f, 4.0f / 5};
  const torch::Tensor grad = log_probs.grad();
  for (int i = 0; i < 5; ++i) EXPECT_NEAR(grad[i].item<float>(), expected[i], 1e-6) << i;
}

TEST(PpoTrainerTest, FullyClippedBatchLeavesTheActorUnchanged) {
  // Every ratio is 2 where the advantage is positive and 0.5 where it is
  // negative: all samples sit in the flat part of the clipped surrogate, so
  // with no entropy bonus the actor gets exactly zero gradient.
  PpoConfig config = SmallConfig();
  config.entropy_coef = 0;
  config.epochs = 2;
  config.minibatches = 2;
  auto trainer = MakeTrainer(config);
  ASSERT_NE(trainer, nullptr);
  std::mt19937 rng(5);
  PpoBatch batch = BanditBatch(*trainer, 64, rng);
  for (int i = 0; i < batch.size; ++i) {
    const bool positive = i % 4 < 2;  // Both signs in both contexts.
    batch.advantages[i] = positive ? 1.0f : -1.0f;
    batch.behaviour_log_probs[i] += positive ? -std::log(2.0f) : std::log(2.0f);
  }
  const std::vector<float> before = AllWeights(trainer->ExportPolicy(0));
  const auto stats = trainer->Train(batch);
  ASSERT_TRUE(stats.ok()) << stats.status();
  EXPECT_DOUBLE_EQ(stats->clip_fraction, 1.0);
  // Mean of (r - 1) - log r over r = 2 and r = 0.5, equally often.
  EXPECT_NEAR(stats->approx_kl, 0.5 * ((1 - std::log(2.0)) + (-0.5 + std::log(2.0))), 1e-4);
  EXPECT_EQ(AllWeights(trainer->ExportPolicy(0)), before);
}

TEST(PpoTrainerTest, SaveThenLoadRestoresEverything) {
  PpoConfig config = SmallConfig();
  config.learning_rate = 3e-3;
  auto original = MakeTrainer(config);
  ASSERT_NE(original, nullptr);
  std::mt19937 rng(9);
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(original->Train(BanditBatch(*original, 64, rng)).ok());
  const std::string path = TempPath("ppo_trainer_test_checkpoint.pt");
  ASSERT_TRUE(original->Save(path).ok());
  EXPECT_FALSE(std::ifstream(path + ".tmp").good()) << "temporary file left behind";

  config.seed = 1234;  // Different initial weights and shuffling.
  auto restored = MakeTrainer(config);
  ASSERT_NE(restored, nullptr);
  ASSERT_NE(AllWeights(restored->ExportPolicy(0)), AllWeights(original->ExportPolicy(0)));
  const absl::Status load = restored->Load(path);
  ASSERT_TRUE(load.ok()) << load;
  EXPECT_EQ(AllWeights(restored->ExportPolicy(0)), AllWeights(original->ExportPolicy(0)));
  EXPECT_EQ(ContextValues(*restored), ContextValues(*original));

  // Optimiser state, normalisers and shuffling RNG came along too: one more
  // identical update keeps the two trainers bit-identical.
  const PpoBatch next = BanditBatch(*original, 64, rng);
  const auto a = original->Train(next);
  const auto b = restored->Train(next);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a->policy_loss, b->policy_loss);
  EXPECT_EQ(a->value_loss, b->value_loss);
  EXPECT_EQ(AllWeights(restored->ExportPolicy(0)), AllWeights(original->ExportPolicy(0)));
  EXPECT_EQ(ContextValues(*restored), ContextValues(*original));
  std::remove(path.c_str());
}

TEST(PpoTrainerTest, LoadRejectsOtherShapesAndMissingFiles) {
  auto original = MakeTrainer(SmallConfig());
  ASSERT_NE(original, nullptr);
  const std::string path = TempPath("ppo_trainer_test_shapes.pt");
  ASSERT_TRUE(original->Save(path).ok());

  auto wider_obs = MakeTrainer(SmallConfig(), /*obs_dim=*/3);
  PpoConfig wider = SmallConfig();
  wider.hidden = 32;
  auto wider_hidden = MakeTrainer(wider);
  ASSERT_TRUE(wider_obs && wider_hidden);
  for (PpoTrainer* t : {wider_obs.get(), wider_hidden.get()}) {
    const std::vector<float> before = AllWeights(t->ExportPolicy(0));
    const absl::Status status = t->Load(path);
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << status;
    EXPECT_THAT(std::string(status.message()), HasSubstr("hidden"));
    EXPECT_EQ(AllWeights(t->ExportPolicy(0)), before);
  }
  EXPECT_EQ(original->Load(TempPath("no_such_checkpoint.pt")).code(), absl::StatusCode::kInternal);
  std::remove(path.c_str());
}

TEST(PpoTrainerTest, InvalidBatchesAreRejectedAndChangeNothing) {
  auto trainer = MakeTrainer(SmallConfig());
  ASSERT_NE(trainer, nullptr);
  std::mt19937 rng(1);
  const PpoBatch good = BanditBatch(*trainer, 4, rng);
  const std::vector<float> weights = AllWeights(trainer->ExportPolicy(0));
  const std::vector<float> values = ContextValues(*trainer);

  struct Case {
    std::function<void(PpoBatch&)> corrupt;
    std::string message;
  };
  const std::vector<Case> cases = {
      {[](PpoBatch& b) { b.actions.pop_back(); }, "batch.actions has 3 elements, expected 4"},
      {[](PpoBatch& b) { b.obs.push_back(0); }, "batch.obs has 9 elements, expected 8"},
      {[](PpoBatch& b) { b.critic_inputs.clear(); },
       "batch.critic_inputs has 0 elements, expected 8"},
      {[](PpoBatch& b) { b.behaviour_log_probs.pop_back(); }, "batch.behaviour_log_probs has 3"},
      {[](PpoBatch& b) { b.advantages.push_back(1); }, "batch.advantages has 5"},
      {[](PpoBatch& b) { b.returns_ext.pop_back(); }, "batch.returns_ext has 3"},
      {[](PpoBatch& b) { b.returns_int.pop_back(); }, "batch.returns_int has 3"},
      {[](PpoBatch& b) { b.size = 0; }, "batch.size"},
      {[](PpoBatch& b) { b.actions[2] = kBanditActions; }, "batch.actions[2] = 5 is out of range"},
      {[](PpoBatch& b) { b.actions[1] = -1; }, "batch.actions[1] = -1 is out of range"},
      {[](PpoBatch& b) { b.returns_int[3] = NAN; }, "batch.returns_int[3] is not finite"},
      {[](PpoBatch& b) { b.behaviour_log_probs[0] = 0.5f; }, "batch.behaviour_log_probs[0]"},
  };
  for (const Case& c : cases) {
    PpoBatch bad = good;
    c.corrupt(bad);
    const auto result = trainer->Train(bad);
    EXPECT_EQ(result.status().code(), absl::StatusCode::kInvalidArgument) << c.message;
    EXPECT_THAT(std::string(result.status().message()), HasSubstr(c.message));
  }
  EXPECT_EQ(AllWeights(trainer->ExportPolicy(0)), weights);
  EXPECT_EQ(ContextValues(*trainer), values);  // Normalisers untouched too.
  EXPECT_TRUE(trainer->Train(good).ok());
  EXPECT_NE(AllWeights(trainer->ExportPolicy(0)), weights);
}

TEST(PpoTrainerTest, ExtremeBehaviourLogProbsKeepTheLossFinite) {
  // Log-probabilities a float holds but no policy gives: without the bound
  // on the log-ratio the ratio overflows to inf (-1e30) or the gradient does
  // (-90), and training failed.
  for (const float poison : {-1e30f, -90.0f, -1e38f}) {
    PpoConfig config = SmallConfig();
    config.epochs = 1;
    config.minibatches = 1;
    auto trainer = MakeTrainer(config);
    ASSERT_NE(trainer, nullptr);
    std::mt19937 rng(2);
    PpoBatch batch = BanditBatch(*trainer, 8, rng);
    for (int i = 0; i < batch.size; ++i) batch.advantages[i] = i == 0 ? -1.0f : 1.0f;
    batch.behaviour_log_probs[0] = poison;
    const std::vector<float> before = AllWeights(trainer->ExportPolicy(0));
    const auto result = trainer->Train(batch);
    ASSERT_TRUE(result.ok()) << poison << ": " << result.status();
    EXPECT_EQ(result->minibatches_skipped, 0) << poison;
    EXPECT_TRUE(std::isfinite(result->policy_loss)) << poison;
    const std::vector<float> after = AllWeights(trainer->ExportPolicy(0));
    EXPECT_NE(after, before) << poison;
    EXPECT_TRUE(std::all_of(after.begin(), after.end(), [](float w) { return std::isfinite(w); })) << poison;
  }
}

TEST(PpoTrainerTest, NonFiniteMinibatchTakesNoStepAndIsCounted) {
  PpoConfig config = SmallConfig();
  config.epochs = 1;
  config.minibatches = 1;
  config.layer_norm = true;
  auto trainer = MakeTrainer(config);
  ASSERT_NE(trainer, nullptr);
  std::mt19937 rng(2);
  PpoBatch batch = BanditBatch(*trainer, 8, rng);
  // Finite, but the input LayerNorm's sum overflows: the loss is NaN.
  batch.obs[0] = batch.obs[1] = 3e38f;
  const std::vector<float> before = AllWeights(trainer->ExportPolicy(0));
  const auto result = trainer->Train(batch);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(result->minibatches_skipped, 1);
  EXPECT_THAT(result->skip_reason, HasSubstr("non-finite"));
  EXPECT_EQ(AllWeights(trainer->ExportPolicy(0)), before);
}

// Every learner option still learns the bandit and the context-dependent
// values, and exports a policy the independent evaluator reads the same way
// as the trainer acts (the bandit is only solved if the export is right).
struct Variant {
  std::string name;
  std::function<void(PpoConfig&)> apply;
};

void PrintTo(const Variant& variant, std::ostream* os) { *os << variant.name; }

class PpoVariantTest : public ::testing::TestWithParam<Variant> {};

TEST_P(PpoVariantTest, LearnsTheBanditAndTheValues) {
  PpoConfig config = SmallConfig();
  config.learning_rate = 3e-3;
  GetParam().apply(config);
  auto trainer = MakeTrainer(config);
  ASSERT_NE(trainer, nullptr);
  std::mt19937 rng(123);
  for (int iteration = 0; iteration < 40; ++iteration) {
    const auto result = trainer->Train(BanditBatch(*trainer, 256, rng));
    ASSERT_TRUE(result.ok()) << result.status();
    EXPECT_TRUE(std::isfinite(result->policy_loss) && std::isfinite(result->value_loss));
  }
  const v1::Policy policy = trainer->ExportPolicy(1);
  EXPECT_EQ(policy.architecture(), config.layer_norm ? v1::Policy::MLP_TANH_LAYERNORM : v1::Policy::MLP_TANH);
  for (int context = 0; context < kContexts; ++context) {
    const std::vector<double> p = Probabilities(policy, OneHot(context));
    EXPECT_GT(p[kRightAction[context]], 0.9) << "context " << context;
  }
  // The critic learns what each context pays (about P(right action) by now).
  const std::vector<float> v = ContextValues(*trainer);
  EXPECT_NEAR(v[0], 1.0f, 0.2f);
  EXPECT_NEAR(v[1], 1.0f, 0.2f);
  if (config.value_heads == 1) {
    EXPECT_EQ(v[2], 0.0f);
    EXPECT_EQ(v[3], 0.0f);
  }
}

INSTANTIATE_TEST_SUITE_P(
    Options, PpoVariantTest,
    ::testing::Values(Variant{"LayerNorm", [](PpoConfig& c) { c.layer_norm = true; }},
                      Variant{"HiddenLayerNormOnly",
                              [](PpoConfig& c) {
                                c.layer_norm = true;
                                c.input_norm = false;
                              }},
                      Variant{"EmaValueNorm", [](PpoConfig& c) { c.value_norm = ValueNorm::kEma; }},
                      Variant{"SeparateOptimizers", [](PpoConfig& c) { c.separate_optimizers = true; }},
                      Variant{"OneValueHead", [](PpoConfig& c) { c.value_heads = 1; }},
                      Variant{"Decoupled", [](PpoConfig& c) { c.objective = PpoObjective::kDecoupled; }},
                      Variant{"ValueClipHuber",
                              [](PpoConfig& c) {
                                c.value_clip = 0.2;
                                c.huber_delta = 1.0;
                                c.hidden_gain = 5.0 / 3.0;
                              }},
                      Variant{"Reference",
                              [](PpoConfig& c) {
                                c.layer_norm = true;
                                c.separate_optimizers = true;
                                c.value_heads = 1;
                                c.value_clip = 0.2;
                                c.value_coef = 1.0;
                              }},
                      Variant{"OnPolicy",
                              [](PpoConfig& c) {
                                c.layer_norm = true;
                                c.input_norm = false;
                                c.value_norm = ValueNorm::kEma;
                                c.separate_optimizers = true;
                                c.value_heads = 1;
                                c.value_coef = 1.0;
                                c.hidden_gain = 5.0 / 3.0;
                              }}),
    [](const ::testing::TestParamInfo<Variant>& info) { return info.param.name; });

void ActorsEvaluateTheExportedLayerNormPolicy(bool input_norm) {
  PpoConfig config = SmallConfig();
  config.layer_norm = true;
  config.input_norm = input_norm;
  config.learning_rate = 3e-3;
  auto trainer = MakeTrainer(config, /*obs_dim=*/kContexts);
  ASSERT_NE(trainer, nullptr);
  std::mt19937 rng(4);
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(trainer->Train(BanditBatch(*trainer, 64, rng)).ok());
  const v1::Policy policy = trainer->ExportPolicy(3);
  EXPECT_EQ(std::count_if(policy.tensors().begin(), policy.tensors().end(),
                          [](const v1::NamedTensor& t) { return t.name().rfind("policy.input_norm.", 0) == 0; }),
            input_norm ? 2 : 0);
  auto mlp = PolicyMlp::FromProto(policy);
  ASSERT_TRUE(mlp.ok()) << mlp.status();
  std::uniform_real_distribution<float> uniform(-2.0f, 2.0f);
  std::vector<float> obs;
  for (int i = 0; i < 8 * kContexts; ++i) obs.push_back(uniform(rng));
  std::vector<float> probs(8 * kBanditActions);
  mlp->Probabilities(obs.data(), 8, probs.data());
  for (int row = 0; row < 8; ++row) {
    const std::vector<double> want =
        Probabilities(policy, std::vector<float>(obs.begin() + row * kContexts, obs.begin() + (row + 1) * kContexts));
    for (int a = 0; a < kBanditActions; ++a) EXPECT_NEAR(probs[row * kBanditActions + a], want[a], 1e-5);
  }
  // A policy missing one of its norms is refused, naming it.
  v1::Policy broken = policy;
  for (int i = 0; i < broken.tensors_size(); ++i) {
    if (broken.tensors(i).name() == "policy.1.norm.bias") broken.mutable_tensors()->DeleteSubrange(i, 1);
  }
  EXPECT_THAT(std::string(PolicyMlp::FromProto(broken).status().message()), HasSubstr("policy.1.norm.bias"));
}

TEST(PpoTrainerTest, ActorsEvaluateTheExportedLayerNormPolicyAsTheLearnerDoes) {
  for (bool input_norm : {true, false}) {
    SCOPED_TRACE(input_norm ? "input and hidden LayerNorms" : "hidden LayerNorms only");
    ActorsEvaluateTheExportedLayerNormPolicy(input_norm);
  }
}


TEST(DecoupledSurrogateTest, ClipsAgainstTheProximalPolicyAndWeightsByBehaviour) {
  // r = pi / pi_prox:  2    1.1   0.5   0.5
  // w = pi_prox / mu:  0.5  2     1     4
  // advantage:         1    1     1    -1
  // w * min term:      0.6  2.2   0.5  -3.2   (clipped, -, -, clipped)
  const torch::Tensor proximal = torch::log(torch::tensor({0.2f, 0.4f, 0.3f, 0.4f}));
  const torch::Tensor behaviour = torch::log(torch::tensor({0.4f, 0.2f, 0.3f, 0.1f}));
  const torch::Tensor log_probs =
      (proximal + torch::log(torch::tensor({2.0f, 1.1f, 0.5f, 0.5f}))).detach().requires_grad_(true);
  const torch::Tensor advantages = torch::tensor({1.0f, 1.0f, 1.0f, -1.0f});
  const torch::Tensor loss =
      internal::DecoupledSurrogateLoss(log_probs, proximal, behaviour, advantages, /*clip=*/0.2);
  EXPECT_NEAR(loss.item<float>(), -(0.6 + 2.2 + 0.5 - 3.2) / 4, 1e-5);
  loss.backward();
  // d loss / d log_prob_i = -w_i * r_i * A_i / 4 where unclipped, else 0.
  const std::vector<float> expected = {0.0f, -2.0f * 1.1f / 4, -0.5f / 4, 0.0f};
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(log_probs.grad()[i].item<float>(), expected[i], 1e-5) << i;

  // With the proximal policy equal to the behaviour one it is plain PPO.
  const torch::Tensor same = internal::DecoupledSurrogateLoss(log_probs, behaviour, behaviour, advantages, 0.2);
  EXPECT_NEAR(same.item<float>(),
              internal::ClippedSurrogateLoss(log_probs, behaviour, advantages, 0.2).item<float>(), 1e-6);
}

// The batch of FullyClippedBatchLeavesTheActorUnchanged: acted by a policy
// that differs from the trainer's (ratio 2 where A > 0, 0.5 where A < 0).
PpoBatch StaleBatch(PpoTrainer& trainer) {
  std::mt19937 rng(5);
  PpoBatch batch = BanditBatch(trainer, 64, rng);
  for (int i = 0; i < batch.size; ++i) {
    const bool positive = i % 4 < 2;
    batch.advantages[i] = positive ? 1.0f : -1.0f;
    batch.behaviour_log_probs[i] += positive ? -std::log(2.0f) : std::log(2.0f);
  }
  return batch;
}

TEST(PpoTrainerTest, DecoupledMeasuresTheClipFromThePolicyItStartsWith) {
  // Plain PPO clips every sample of this stale batch (its ratios to the
  // behaviour policy are 2 and 0.5) and learns nothing; decoupled PPO starts
  // each sample at ratio 1 to its proximal policy, so it learns.
  PpoConfig config = SmallConfig();
  config.entropy_coef = 0;
  config.epochs = 1;
  config.minibatches = 1;
  for (PpoObjective objective : {PpoObjective::kBehaviour, PpoObjective::kDecoupled}) {
    config.objective = objective;
    auto trainer = MakeTrainer(config);
    ASSERT_NE(trainer, nullptr);
    const PpoBatch batch = StaleBatch(*trainer);
    const std::vector<float> before = AllWeights(trainer->ExportPolicy(0));
    const auto stats = trainer->Train(batch);
    ASSERT_TRUE(stats.ok()) << stats.status();
    // Staleness is measured the same way by both: w = pi_start / mu is 1/2 or 2.
    EXPECT_NEAR(stats->behaviour_kl, 0.5 * ((0.5 - 1 + std::log(2.0)) + (2 - 1 - std::log(2.0))), 1e-4);
    if (objective == PpoObjective::kBehaviour) {
      EXPECT_DOUBLE_EQ(stats->clip_fraction, 1.0);
      EXPECT_EQ(AllWeights(trainer->ExportPolicy(0)), before);
    } else {
      // One minibatch of one epoch: the forward pass is the proximal policy itself.
      EXPECT_DOUBLE_EQ(stats->clip_fraction, 0.0);
      EXPECT_NEAR(stats->approx_kl, 0.0, 1e-7);
      EXPECT_NE(AllWeights(trainer->ExportPolicy(0)), before);
    }
  }
}

void OptionsRoundTripThroughCheckpoints(const PpoConfig& config) {
  auto original = MakeTrainer(config);
  ASSERT_NE(original, nullptr);
  std::mt19937 rng(9);
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(original->Train(BanditBatch(*original, 64, rng)).ok());
  const std::string path = TempPath("ppo_trainer_test_options.pt");
  ASSERT_TRUE(original->Save(path).ok());

  PpoConfig reseeded = config;
  reseeded.seed = 99;
  auto restored = MakeTrainer(reseeded);
  ASSERT_NE(restored, nullptr);
  ASSERT_TRUE(restored->Load(path).ok());
  const PpoBatch next = BanditBatch(*original, 64, rng);
  ASSERT_TRUE(original->Train(next).ok());
  ASSERT_TRUE(restored->Train(next).ok());
  EXPECT_EQ(AllWeights(restored->ExportPolicy(0)), AllWeights(original->ExportPolicy(0)));
  EXPECT_EQ(ContextValues(*restored), ContextValues(*original));

  for (const auto& [what, change] : std::vector<std::pair<std::string, std::function<void(PpoConfig&)>>>{
           {"layer_norm", [](PpoConfig& c) { c.layer_norm = !c.layer_norm; }},
           {"input_norm", [](PpoConfig& c) { c.input_norm = !c.input_norm; }},
           {"value_heads", [](PpoConfig& c) { c.value_heads = 3 - c.value_heads; }},
           {"optimizers", [](PpoConfig& c) { c.separate_optimizers = !c.separate_optimizers; }},
           {"value_norm", [](PpoConfig& c) {
              c.value_norm = c.value_norm == ValueNorm::kEma ? ValueNorm::kBatch : ValueNorm::kEma;
            }}}) {
    PpoConfig other = config;
    change(other);
    auto mismatched = MakeTrainer(other);
    ASSERT_NE(mismatched, nullptr);
    const std::vector<float> before = AllWeights(mismatched->ExportPolicy(0));
    const absl::Status status = mismatched->Load(path);
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << what << ": " << status;
    EXPECT_THAT(std::string(status.message()), HasSubstr("(layer norms, value_heads, optimizers, value_norm)"))
        << what;
    EXPECT_EQ(AllWeights(mismatched->ExportPolicy(0)), before) << what;
  }
  std::remove(path.c_str());
}

TEST(PpoTrainerTest, OptionsRoundTripThroughCheckpointsAndMismatchesAreRefused) {
  PpoConfig config = SmallConfig();
  config.learning_rate = 3e-3;
  config.layer_norm = true;
  config.separate_optimizers = true;
  config.value_heads = 1;
  {
    SCOPED_TRACE("input and hidden LayerNorms, batch normalisers");
    OptionsRoundTripThroughCheckpoints(config);
  }
  config.input_norm = false;
  config.value_norm = ValueNorm::kEma;
  config.value_heads = 2;
  {
    SCOPED_TRACE("hidden LayerNorms only, moving-average normalisers");
    OptionsRoundTripThroughCheckpoints(config);
  }
}

// on-policy's ValueNorm worked by hand: beta = 0.99999, debiased averages,
// variance floored at 0.01; the batch normaliser's std floored at 0.01.
TEST(ReturnNormaliserTest, MovingAveragesAsOnPolicyAndFloorsAsDocumented) {
  using internal::ReturnNormaliser;
  ReturnNormaliser ema(ValueNorm::kEma);
  EXPECT_DOUBLE_EQ(ema.mean(), 0.0);
  EXPECT_NEAR(ema.std(), 0.1, 1e-12);  // Nothing seen: the floor.
  ema.Update(torch::tensor({1.0f, 3.0f}));
  // Averages 2e-5 and 5e-5 over a debiasing term of 1e-5: mean 2, var 5 - 4.
  EXPECT_NEAR(ema.mean(), 2.0, 1e-9);
  EXPECT_NEAR(ema.std(), 1.0, 1e-9);
  ema.Update(torch::tensor({0.0f, 0.0f}));
  const double beta = internal::kEmaBeta;
  const double mean = 2 * beta / (1 + beta), var = 5 * beta / (1 + beta) - mean * mean;
  EXPECT_NEAR(ema.mean(), mean, 1e-9);
  EXPECT_NEAR(ema.std(), std::sqrt(var), 1e-9);
  EXPECT_TRUE(torch::allclose(ema.Normalise(torch::tensor({1.0f})), torch::tensor({(1 - mean) / std::sqrt(var)})));

  // A checkpoint's tensor restores the state; one that is no such state is refused.
  auto restored = ReturnNormaliser::FromTensor(ValueNorm::kEma, ema.ToTensor(), "value_norm_ext");
  ASSERT_TRUE(restored.ok()) << restored.status();
  EXPECT_EQ(restored->mean(), ema.mean());
  EXPECT_EQ(restored->std(), ema.std());
  const auto bad = ReturnNormaliser::FromTensor(ValueNorm::kEma, torch::tensor({0.0, 1.0, 2.0}, torch::kFloat64),
                                                "value_norm_int");
  EXPECT_EQ(bad.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(bad.status().message()), HasSubstr("value_norm_int"));

  // Constant returns: the moving average's std stays at 0.1, the batch one's at 0.01.
  ReturnNormaliser constant_ema(ValueNorm::kEma), constant_batch(ValueNorm::kBatch);
  for (int i = 0; i < 3; ++i) {
    constant_ema.Update(torch::full({64}, 2.0f));
    constant_batch.Update(torch::full({64}, 2.0f));
  }
  EXPECT_NEAR(constant_ema.mean(), 2.0, 1e-9);
  EXPECT_NEAR(constant_ema.std(), 0.1, 1e-9);
  EXPECT_NEAR(constant_batch.mean(), 2.0, 1e-5);
  EXPECT_NEAR(constant_batch.std(), 0.01, 1e-9);
}

TEST(PpoTrainerTest, CreateRejectsBadOptions) {
  std::vector<PpoConfig> bad(4, SmallConfig());
  bad[0].value_heads = 4;
  bad[1].hidden_gain = 0;
  bad[2].value_clip = -1;
  bad[3].huber_delta = -0.5;
  for (size_t i = 0; i < bad.size(); ++i) {
    const auto t = PpoTrainer::Create(bad[i], 3, 4, 5);
    EXPECT_EQ(t.status().code(), absl::StatusCode::kInvalidArgument) << "config " << i;
  }
  EXPECT_EQ(ParsePpoObjective("decoupled").value(), PpoObjective::kDecoupled);
  EXPECT_THAT(std::string(ParsePpoObjective("proximal").status().message()), HasSubstr("behaviour or decoupled"));
}

}  // namespace
}  // namespace imca::learner
