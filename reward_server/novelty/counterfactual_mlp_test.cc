#include "reward_server/novelty/counterfactual_mlp.h"

#include <algorithm>
#include <cstdint>
#include <functional>
#include <random>
#include <stdexcept>
#include <utility>
#include <vector>

#include "gtest/gtest.h"

namespace imca::reward {
namespace {

// A net's tail with its own storage.
struct Tail {
  std::vector<std::vector<float>> weights, biases;
  MlpTail view;
};

Tail RandomTail(const std::vector<int>& widths, std::mt19937* rng) {
  std::normal_distribution<float> normal;
  Tail tail;
  for (size_t l = 1; l < widths.size(); ++l) {
    tail.weights.emplace_back(widths[l] * widths[l - 1]);
    tail.biases.emplace_back(widths[l]);
    for (float& w : tail.weights.back()) w = normal(*rng) * 0.3f;
    for (float& b : tail.biases.back()) b = normal(*rng) * 0.1f;
  }
  for (size_t l = 0; l + 1 < widths.size(); ++l) {
    tail.view.layers.push_back({tail.weights[l].data(), tail.biases[l].data(), widths[l + 1], widths[l]});
  }
  return tail;
}

// The definition, one row at a time, in double.
std::vector<double> Embed(const MlpTail& tail, std::vector<double> z) {
  for (const MlpTail::Layer& layer : tail.layers) {
    std::vector<double> y(layer.out);
    for (int o = 0; o < layer.out; ++o) {
      y[o] = layer.bias[o];
      for (int k = 0; k < layer.in; ++k) y[o] += layer.weight[o * layer.in + k] * std::max(0.0, z[k]);
    }
    z = std::move(y);
  }
  return z;
}

struct Case {
  int64_t N;
  int n, A, H;
  std::vector<int> tail;  // Widths after the first layer's H.
  int threads = 1;
};

class CounterfactualMlpTest : public ::testing::TestWithParam<Case> {};

TEST_P(CounterfactualMlpTest, EveryRowEqualsTheNetsOnThatRow) {
  const Case c = GetParam();
  std::mt19937 rng(7);
  std::normal_distribution<float> normal;
  std::vector<int> widths = {c.H};
  widths.insert(widths.end(), c.tail.begin(), c.tail.end());
  const Tail target = RandomTail(widths, &rng), predictor = RandomTail(widths, &rng);
  auto random = [&](size_t size) {
    std::vector<float> v(size);
    for (float& x : v) x = normal(rng);
    return v;
  };
  const std::vector<float> ht = random(c.N * c.H), hp = random(c.N * c.H);
  const std::vector<float> ct = random(c.n * c.A * c.H), cp = random(c.n * c.A * c.H);
  const std::vector<float> taken_novelty = random(c.N);
  std::vector<int64_t> taken(c.N * c.n);
  for (int64_t& t : taken) t = rng() % c.A;
  std::vector<float> out(c.N * c.n * c.A, -1.0f);
  CounterfactualNovelties(target.view, predictor.view, c.N, c.n, c.A, c.H, ht.data(), hp.data(), ct.data(),
                          cp.data(), taken.data(), taken_novelty.data(), out.data(), c.threads);
  for (int64_t i = 0; i < c.N; ++i) {
    for (int s = 0; s < c.n; ++s) {
      const int64_t t = taken[i * c.n + s];
      for (int u = 0; u < c.A; ++u) {
        const float got = out[(i * c.n + s) * c.A + u];
        if (u == t) {
          EXPECT_EQ(got, taken_novelty[i]) << "taken row i=" << i << " s=" << s;
          continue;
        }
        std::vector<double> zt(c.H), zp(c.H);
        for (int k = 0; k < c.H; ++k) {
          zt[k] = double{ht[i * c.H + k]} + ct[(s * c.A + u) * c.H + k] - ct[(s * c.A + t) * c.H + k];
          zp[k] = double{hp[i * c.H + k]} + cp[(s * c.A + u) * c.H + k] - cp[(s * c.A + t) * c.H + k];
        }
        const std::vector<double> et = Embed(target.view, zt), ep = Embed(predictor.view, zp);
        double want = 0;
        for (size_t k = 0; k < et.size(); ++k) want += (et[k] - ep[k]) * (et[k] - ep[k]);
        want /= static_cast<double>(et.size());
        EXPECT_NEAR(got, want, 1e-4 * (1 + want)) << "i=" << i << " s=" << s << " u=" << u;
      }
    }
  }
}

// n (A - 1) not a multiple of 4 and width 128: rows in different places of
// a block would round differently in Eigen's kernel.
TEST(CounterfactualMlpSplitTest, ValuesDoNotDependOnTheThreads) {
  std::mt19937 rng(11);
  std::normal_distribution<float> normal;
  const int64_t N = 301;
  const int n = 3, A = 4, H = 128;
  const Tail target = RandomTail({H, 128, 64}, &rng), predictor = RandomTail({H, 128, 64}, &rng);
  auto random = [&](size_t size) {
    std::vector<float> v(size);
    for (float& x : v) x = normal(rng);
    return v;
  };
  const std::vector<float> ht = random(N * H), hp = random(N * H), ct = random(n * A * H), cp = random(n * A * H);
  const std::vector<float> taken_novelty = random(N);
  std::vector<int64_t> taken(N * n);
  for (int64_t& t : taken) t = rng() % A;
  int alongside_runs = 0;
  auto run = [&](int threads, bool alongside) {
    std::vector<float> out(N * n * A);
    std::function<void()> work;
    if (alongside) work = [&] { ++alongside_runs; };
    CounterfactualNovelties(target.view, predictor.view, N, n, A, H, ht.data(), hp.data(), ct.data(), cp.data(),
                            taken.data(), taken_novelty.data(), out.data(), threads, work);
    return out;
  };
  const std::vector<float> one = run(1, false);
  EXPECT_EQ(one, run(2, false));
  EXPECT_EQ(one, run(3, false));
  // Work alongside changes nothing and runs once a call, at any threads.
  EXPECT_EQ(one, run(1, true));
  EXPECT_EQ(one, run(2, true));
  EXPECT_EQ(one, run(3, true));
  EXPECT_EQ(alongside_runs, 3);
}

TEST(CounterfactualMlpSplitTest, AnErrorAlongsideIsRethrownAfterTheThreadsEnd) {
  std::mt19937 rng(5);
  const int64_t N = 40;
  const int n = 2, A = 3, H = 8;
  const Tail target = RandomTail({H, 8, 4}, &rng), predictor = RandomTail({H, 8, 4}, &rng);
  const std::vector<float> ht(N * H, 0.5f), hp(N * H, -0.5f), ct(n * A * H, 0.1f), cp(n * A * H, 0.2f);
  const std::vector<float> taken_novelty(N, 1.0f);
  const std::vector<int64_t> taken(N * n, 1);
  std::vector<float> out(N * n * A);
  for (int threads : {1, 2}) {
    EXPECT_THROW(CounterfactualNovelties(target.view, predictor.view, N, n, A, H, ht.data(), hp.data(), ct.data(),
                                         cp.data(), taken.data(), taken_novelty.data(), out.data(), threads,
                                         [] { throw std::runtime_error("alongside"); }),
                 std::runtime_error)
        << "threads=" << threads;
  }
}

INSTANTIATE_TEST_SUITE_P(
    Shapes, CounterfactualMlpTest,
    ::testing::Values(Case{3, 2, 5, 8, {8, 4}},        // RND's shape, small.
                      Case{70, 4, 5, 16, {16, 16, 6}},  // Several blocks, the last one short.
                      Case{5, 3, 4, 6, {}},             // One linear layer: the pre-activation is the embedding.
                      Case{4, 2, 1, 5, {3}},            // One action: no counterfactual row.
                      Case{2, 70, 5, 4, {4}},           // One transition's rows overflow a block.
                      Case{70, 3, 5, 16, {16, 6}, 2},   // Two threads.
                      Case{2, 3, 5, 8, {8}, 4}));       // More threads than transitions.

}  // namespace
}  // namespace imca::reward
