#include <torch/torch.h>

#include <cmath>
#include <filesystem>
#include <memory>

#include "common/nn/archive.h"
#include "common/nn/blas_kernels.h"
#include "common/nn/mlp.h"
#include "common/nn/running_moments.h"
#include "common/nn/torch_status.h"
#include "gtest/gtest.h"

namespace imca::nn {
namespace {

TEST(MlpTest, InitialWeightsAreAFunctionOfTheSeedAlone) {
  torch::manual_seed(7);
  Mlp a(MlpOptions({5, 8, 3}).seed(11));
  Mlp b(MlpOptions({5, 8, 3}).seed(11));
  Mlp c(MlpOptions({5, 8, 3}).seed(12));
  // Building a network does not reseed torch's global generator: a draw
  // after it differs from the first draw after manual_seed(11).
  const torch::Tensor after = torch::rand({4});
  torch::manual_seed(11);
  EXPECT_FALSE(torch::equal(after, torch::rand({4})));
  for (size_t i = 0; i < a->layers().size(); ++i) {
    EXPECT_TRUE(torch::equal(a->layers()[i]->weight, b->layers()[i]->weight));
    EXPECT_FALSE(torch::equal(a->layers()[i]->weight, c->layers()[i]->weight));
    EXPECT_EQ(a->layers()[i]->bias.abs().sum().item<float>(), 0.0f);
  }
  torch::manual_seed(99);
  Mlp d(MlpOptions({5, 8, 3}).seed(11));
  EXPECT_TRUE(torch::equal(a->layers()[0]->weight, d->layers()[0]->weight));
}

TEST(MlpTest, OrthogonalInitGivesOrthonormalRowsOrColumnsTimesGain) {
  at::Generator generator = at::detail::createCPUGenerator(3);
  torch::Tensor wide = torch::empty({4, 9});
  OrthogonalInit(wide, 2.0, generator);
  EXPECT_TRUE(torch::allclose(wide.mm(wide.t()), 4.0 * torch::eye(4), 1e-4, 1e-4));
  torch::Tensor tall = torch::empty({9, 4});
  OrthogonalInit(tall, 0.5, generator);
  EXPECT_TRUE(torch::allclose(tall.t().mm(tall), 0.25 * torch::eye(4), 1e-4, 1e-4));
}

TEST(MlpTest, ForwardIsLinearActivationLinear) {
  Mlp relu(MlpOptions({2, 2, 1}));
  ASSERT_TRUE(SetLinear(relu, 0, {1, 0, 0, -1}, {0, 0}).ok());
  ASSERT_TRUE(SetLinear(relu, 1, {2, 3}, {0.5}).ok());
  // h = relu([x0, -x1]); y = 2 h0 + 3 h1 + 0.5.
  EXPECT_FLOAT_EQ(relu->forward(torch::tensor({{1.0f, -2.0f}}))[0][0].item<float>(), 2 + 6 + 0.5f);
  EXPECT_FLOAT_EQ(relu->forward(torch::tensor({{-1.0f, 2.0f}}))[0][0].item<float>(), 0.5f);
  Mlp tanh(MlpOptions({2, 2, 1}).activation(Activation::kTanh));
  ASSERT_TRUE(SetLinear(tanh, 0, {1, 0, 0, -1}, {0, 0}).ok());
  ASSERT_TRUE(SetLinear(tanh, 1, {2, 3}, {0.5}).ok());
  EXPECT_NEAR(tanh->forward(torch::tensor({{1.0f, -2.0f}}))[0][0].item<float>(),
              2 * std::tanh(1.0) + 3 * std::tanh(2.0) + 0.5, 1e-5);
  EXPECT_FALSE(SetLinear(tanh, 2, {1}, {1}).ok());
  EXPECT_FALSE(SetLinear(tanh, 0, {1}, {1}).ok());
}

TEST(MlpTest, ForwardFromALayerContinuesTheForwardPass) {
  for (bool layer_norm : {false, true}) {
    Mlp mlp(MlpOptions({4, 6, 5, 2}).layer_norm(layer_norm).seed(3));
    const torch::Tensor x = torch::randn({7, 4});
    torch::nn::LayerNorm input_norm = mlp->input_norm();  // A holder sharing the module.
    const torch::Tensor in = layer_norm ? input_norm->forward(x) : x;
    EXPECT_TRUE(torch::allclose(mlp->ForwardFrom(mlp->layers()[0]->forward(in), 0), mlp->forward(x)));
    // The first layer in two parts (columns 0-1 and 2-3), as MADDPG's critic.
    const torch::Tensor w = mlp->layers()[0]->weight;
    const torch::Tensor parts = torch::matmul(in.narrow(1, 0, 2), w.narrow(1, 0, 2).t()) +
                                torch::matmul(in.narrow(1, 2, 2), w.narrow(1, 2, 2).t()) + mlp->layers()[0]->bias;
    EXPECT_TRUE(torch::allclose(mlp->ForwardFrom(parts, 0), mlp->forward(x), 1e-5, 1e-6));
  }
}

TEST(MlpTest, LayerNormModulesAreNamedAsCheckpointsExpect) {
  Mlp mlp(MlpOptions({3, 4, 4, 2}).layer_norm(true));
  std::vector<std::string> names;
  for (const auto& item : mlp->named_parameters()) names.push_back(item.key());
  EXPECT_EQ(names, (std::vector<std::string>{"input_norm.weight", "input_norm.bias", "0.weight", "0.bias",
                                             "norm0.weight", "norm0.bias", "1.weight", "1.bias", "norm1.weight",
                                             "norm1.bias", "2.weight", "2.bias"}));
  // Without the input's LayerNorm: the hidden ones only.
  Mlp hidden_only(MlpOptions({3, 4, 4, 2}).layer_norm(true).input_norm(false));
  names.clear();
  for (const auto& item : hidden_only->named_parameters()) names.push_back(item.key());
  EXPECT_EQ(names, (std::vector<std::string>{"0.weight", "0.bias", "norm0.weight", "norm0.bias", "1.weight",
                                             "1.bias", "norm1.weight", "norm1.bias", "2.weight", "2.bias"}));
  EXPECT_TRUE(hidden_only->input_norm().is_empty());
}

TEST(SoftUpdateTest, MovesTauOfTheWayAndTauOneCopies) {
  Mlp from(MlpOptions({2, 1}).seed(1)), to(MlpOptions({2, 1}).seed(2));
  ASSERT_TRUE(SetLinear(from, 0, {1, 1}, {1}).ok());
  ASSERT_TRUE(SetLinear(to, 0, {0, 2}, {-1}).ok());
  SoftUpdate(*to, *from, 0.25);
  EXPECT_TRUE(torch::allclose(to->layers()[0]->weight, torch::tensor({{0.25f, 1.75f}})));
  EXPECT_TRUE(torch::allclose(to->layers()[0]->bias, torch::tensor({-0.5f})));
  SoftUpdate(*to, *from, 1.0);
  EXPECT_TRUE(torch::equal(to->layers()[0]->weight, from->layers()[0]->weight));
}

TEST(RunningMomentsTest, MergedBatchesEqualOneBatchOfAllRows) {
  RunningMoments merged(2);
  merged.Update(torch::tensor({{1.0, 10.0}, {3.0, 20.0}}));
  merged.Update(torch::tensor({{5.0, 30.0}}));
  // Exactly the moments of the three rows pooled with the prior
  // pseudo-sample (count c0 = 1e-4, mean 0, var 1).
  const double c0 = 1e-4;
  const auto pooled = [&](std::vector<double> x, int col) {
    double mean = 0;
    for (double v : x) mean += v;
    mean /= (c0 + 3);
    double m2 = c0 * (1 + mean * mean);
    for (double v : x) m2 += (v - mean) * (v - mean);
    EXPECT_NEAR(merged.mean()[col].item<double>(), mean, 1e-9);
    EXPECT_NEAR(merged.var()[col].item<double>(), m2 / (c0 + 3), 1e-9);
  };
  pooled({1, 3, 5}, 0);
  pooled({10, 20, 30}, 1);
  EXPECT_NEAR(merged.count(), 3.0, 1e-3);
  RunningMoments scalar;
  scalar.Update(std::vector<float>{2, 4});
  EXPECT_NEAR(scalar.scalar_mean(), 3.0, 1e-3);
  EXPECT_NEAR(scalar.scalar_var(), 1.0, 1e-3);
}

TEST(RunningMomentsTest, TensorRoundTripAndBadTensorsAreRefused) {
  RunningMoments m(2);
  m.Update(torch::tensor({{1.0, 2.0}, {3.0, 5.0}}));
  absl::StatusOr<RunningMoments> back = RunningMoments::FromTensor(m.ToTensor(), 2, "m");
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_TRUE(torch::equal(back->mean(), m.mean()));
  EXPECT_TRUE(torch::equal(back->var(), m.var()));
  EXPECT_EQ(back->count(), m.count());
  EXPECT_EQ(RunningMoments::FromTensor(m.ToTensor(), 1, "m").status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(RunningMoments::FromTensor(torch::tensor({0.0, -1.0, 1.0}, torch::kFloat64), 1, "m").status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(TorchCallTest, ThrowsBecomeInternalNamingTheCall) {
  const absl::Status status =
      TorchCall("matmul", [] { (void)torch::ones({2, 3}).mm(torch::ones({2, 3})); });
  EXPECT_EQ(status.code(), absl::StatusCode::kInternal);
  EXPECT_NE(status.message().find("matmul: "), std::string::npos) << status;
  const absl::StatusOr<int> value = TorchCall("value", []() -> absl::StatusOr<int> { return 3; });
  ASSERT_TRUE(value.ok());
  EXPECT_EQ(*value, 3);
}

TEST(ArchiveTest, TagMismatchAndMissingFileAreTypedErrors) {
  const std::string path = (std::filesystem::temp_directory_path() / "nn_test_archive.pt").string();
  ASSERT_TRUE(SaveArchive(path, "tag-a", [](torch::serialize::OutputArchive& a) {
                a.write("x", torch::ones({2}));
              }).ok());
  torch::Tensor x;
  EXPECT_TRUE(LoadArchive(path, "tag-a", [&](torch::serialize::InputArchive& a) { a.read("x", x); }).ok());
  EXPECT_TRUE(torch::equal(x, torch::ones({2})));
  EXPECT_EQ(LoadArchive(path, "tag-b", [](torch::serialize::InputArchive&) {}).code(),
            absl::StatusCode::kFailedPrecondition);
  EXPECT_EQ(LoadArchive(path, "tag-a", [&](torch::serialize::InputArchive& a) { a.read("y", x); }).code(),
            absl::StatusCode::kDataLoss);
  EXPECT_EQ(LoadArchive(path + ".none", "tag-a", [](torch::serialize::InputArchive&) {}).code(),
            absl::StatusCode::kNotFound);
  std::filesystem::remove(path);
}


// Two equal nets, each with an Adam that took the same steps.
struct Trained {
  Mlp net;
  std::unique_ptr<torch::optim::Adam> adam;
  explicit Trained(int steps) : net(MlpOptions({4, 6, 2}).seed(3)) {
    adam = std::make_unique<torch::optim::Adam>(net->parameters(), torch::optim::AdamOptions(1e-2));
    for (int i = 0; i < steps; ++i) Step();
  }
  void Step() {
    adam->zero_grad();
    net->forward(torch::ones({3, 4})).pow(2).sum().backward();
    adam->step();
  }
};

TEST(ArchiveTest, EqualAdamStatesWriteEqualBytesAndReadBackExactly) {
  Trained a(3), b(3);  // Other tensors, other addresses.
  const auto bytes = [](const Trained& t) {
    return SerializeArchive("t", [&](torch::serialize::OutputArchive& archive) { WriteAdam(archive, "adam", *t.adam); });
  };
  const absl::StatusOr<std::string> of_a = bytes(a), of_b = bytes(b);
  ASSERT_TRUE(of_a.ok() && of_b.ok());
  EXPECT_EQ(*of_a, *of_b);
  // Read into a fresh optimiser over the same weights, it steps as the original.
  const std::string path = (std::filesystem::temp_directory_path() / "nn_test_adam.pt").string();
  ASSERT_TRUE(SaveArchive(path, "t", [&](torch::serialize::OutputArchive& archive) {
                WriteAdam(archive, "adam", *a.adam);
              }).ok());
  Trained c(0);
  {
    torch::NoGradGuard no_grad;
    for (size_t i = 0; i < c.net->parameters().size(); ++i) c.net->parameters()[i].copy_(a.net->parameters()[i]);
  }
  ASSERT_TRUE(LoadArchive(path, "t", [&](torch::serialize::InputArchive& archive) {
                ReadAdam(archive, "adam", *c.adam);
              }).ok());
  a.Step();
  c.Step();
  for (size_t i = 0; i < a.net->parameters().size(); ++i) {
    EXPECT_TRUE(torch::equal(a.net->parameters()[i], c.net->parameters()[i])) << i;
  }
  // An optimiser that took no step writes no moments, and reads back as none.
  Trained fresh(0);
  ASSERT_TRUE(SaveArchive(path, "t", [&](torch::serialize::OutputArchive& archive) {
                WriteAdam(archive, "adam", *fresh.adam);
              }).ok());
  ASSERT_TRUE(LoadArchive(path, "t", [&](torch::serialize::InputArchive& archive) {
                ReadAdam(archive, "adam", *c.adam);
              }).ok());
  EXPECT_TRUE(c.adam->state().empty());
  std::filesystem::remove(path);
}

TEST(BlasKernelsTest, OlderKernelsThanTheCpuRunsAreReplaced) {
  const CpuFeatures avx512{.avx2_fma = true, .avx512 = true}, avx2{.avx2_fma = true}, sse{};
  // OpenBLAS 0.3.21's fallback on a CPU model it does not know.
  EXPECT_EQ(BetterCoreType("Prescott", avx512), "SkylakeX");
  EXPECT_EQ(BetterCoreType("Prescott", avx2), "Haswell");
  EXPECT_EQ(BetterCoreType("SANDYBRIDGE", avx2), "Haswell");
  EXPECT_EQ(BetterCoreType("Haswell", avx512), "SkylakeX");
  // Kernels that fit the CPU stay, and so does anything on an older CPU.
  EXPECT_EQ(BetterCoreType("SkylakeX", avx512), "");
  EXPECT_EQ(BetterCoreType("cooperlake", avx512), "");
  EXPECT_EQ(BetterCoreType("Haswell", avx2), "");
  EXPECT_EQ(BetterCoreType("Zen", avx2), "");
  EXPECT_EQ(BetterCoreType("Prescott", sse), "");
  EXPECT_EQ(BetterCoreType("", sse), "");
}

TEST(BlasKernelsTest, RestartsOnlyWhenUnsetAndOpenBlasChoseOlderKernels) {
  const CpuFeatures avx512{.avx2_fma = true, .avx512 = true};
  EXPECT_EQ(CoreTypeToForce(nullptr, "Prescott", avx512), "SkylakeX");
  // Set by a user, or by the restart itself (which must not loop), even to
  // the old kernels or to nothing.
  EXPECT_EQ(CoreTypeToForce("Prescott", "Prescott", avx512), "");
  EXPECT_EQ(CoreTypeToForce("", "Prescott", avx512), "");
  // No OpenBLAS loaded (the reference BLAS, or MKL).
  EXPECT_EQ(CoreTypeToForce(nullptr, nullptr, avx512), "");
  EXPECT_EQ(CoreTypeToForce(nullptr, "SkylakeX", avx512), "");
}

}  // namespace
}  // namespace imca::nn
