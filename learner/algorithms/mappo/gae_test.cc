#include "learner/algorithms/mappo/gae.h"

#include <cstdint>
#include <memory>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace imca::learner {
namespace {

using ::testing::ElementsAre;
using ::testing::FloatEq;
using ::testing::Pointwise;

// std::vector<bool> has no data(); the flags are kept as plain bool arrays.
struct GaeCase {
  int64_t T = 0;
  int64_t M = 0;
  std::vector<float> rewards;       // [T][M]
  std::vector<float> values;        // [T+1][M]
  std::vector<float> final_values;  // [T][M]
  std::unique_ptr<bool[]> terminated;
  std::unique_ptr<bool[]> truncated;
  float gamma = 0.5f;
  float lambda = 0.5f;

  GaeCase(int64_t t, int64_t m)
      : T(t),
        M(m),
        rewards(t * m, 0.0f),
        values((t + 1) * m, 0.0f),
        final_values(t * m, 0.0f),
        terminated(new bool[t * m]()),
        truncated(new bool[t * m]()) {}

  struct Result {
    std::vector<float> advantages;
    std::vector<float> returns;
  };

  Result Run() const {
    Result r{std::vector<float>(T * M, -999.0f), std::vector<float>(T * M, -999.0f)};
    ComputeGae(T, M, rewards.data(), values.data(), final_values.data(), terminated.get(),
               truncated.get(), gamma, lambda, r.advantages.data(), r.returns.data());
    return r;
  }
};

// The single-stream case used by several tests (gamma = lambda = 0.5, so
// gamma * lambda = 0.25 and every number below is exact in float):
//   rewards r = [1, 2, 3], values V = [0.5, 1, 1.5, 2].
GaeCase BaseCase() {
  GaeCase c(3, 1);
  c.rewards = {1, 2, 3};
  c.values = {0.5f, 1, 1.5f, 2};
  return c;
}

TEST(GaeTest, NoEpisodeEnd) {
  // delta_0 = 1 + 0.5*1   - 0.5 = 1
  // delta_1 = 2 + 0.5*1.5 - 1   = 1.75
  // delta_2 = 3 + 0.5*2   - 1.5 = 2.5      (values[3] bootstraps the block)
  // gae_2 = 2.5; gae_1 = 1.75 + 0.25*2.5 = 2.375; gae_0 = 1 + 0.25*2.375 = 1.59375
  const auto r = BaseCase().Run();
  EXPECT_THAT(r.advantages, ElementsAre(FloatEq(1.59375f), FloatEq(2.375f), FloatEq(2.5f)));
  EXPECT_THAT(r.returns, ElementsAre(FloatEq(2.09375f), FloatEq(3.375f), FloatEq(4.0f)));
}

TEST(GaeTest, TerminationInTheMiddle) {
  GaeCase c = BaseCase();
  c.terminated[1] = true;
  // delta_2 = 2.5, gae_2 = 2.5
  // delta_1 = 2 + 0 - 1 = 1, and the recursion restarts: gae_1 = 1
  // delta_0 = 1, gae_0 = 1 + 0.25*1 = 1.25
  const auto r = c.Run();
  EXPECT_THAT(r.advantages, ElementsAre(FloatEq(1.25f), FloatEq(1.0f), FloatEq(2.5f)));
  EXPECT_THAT(r.returns, ElementsAre(FloatEq(1.75f), FloatEq(2.0f), FloatEq(4.0f)));
}

TEST(GaeTest, TruncationBootstrapsWithFinalValue) {
  GaeCase c = BaseCase();
  c.truncated[1] = true;
  c.final_values[1] = 4.0f;  // V of the state reached at the time limit.
  // delta_2 = 2.5, gae_2 = 2.5
  // delta_1 = 2 + 0.5*4 - 1 = 3, recursion restarts: gae_1 = 3
  // delta_0 = 1, gae_0 = 1 + 0.25*3 = 1.75
  const auto r = c.Run();
  EXPECT_THAT(r.advantages, ElementsAre(FloatEq(1.75f), FloatEq(3.0f), FloatEq(2.5f)));
  EXPECT_THAT(r.returns, ElementsAre(FloatEq(2.25f), FloatEq(4.0f), FloatEq(4.0f)));

  // values[2] belongs to the next episode: changing it moves only step 2.
  c.values[2] = 100.0f;
  const auto moved = c.Run();
  EXPECT_FLOAT_EQ(moved.advantages[0], 1.75f);
  EXPECT_FLOAT_EQ(moved.advantages[1], 3.0f);
  EXPECT_FLOAT_EQ(moved.advantages[2], 3.0f + 0.5f * 2.0f - 100.0f);
}

TEST(GaeTest, TerminationWinsOverTruncation) {
  GaeCase c = BaseCase();
  c.terminated[1] = true;
  c.truncated[1] = true;
  c.final_values[1] = 4.0f;  // Must be ignored: a terminal state has no future.
  const auto r = c.Run();
  EXPECT_THAT(r.advantages, ElementsAre(FloatEq(1.25f), FloatEq(1.0f), FloatEq(2.5f)));
}

TEST(GaeTest, TwoStreamsAreIndependent) {
  // Stream 0 is the base case with no end; stream 1 has the same rewards and
  // values but terminates at t = 1. Layout is time-major: index t*M + m.
  GaeCase c(3, 2);
  c.rewards = {1, 1, 2, 2, 3, 3};
  c.values = {0.5f, 0.5f, 1, 1, 1.5f, 1.5f, 2, 2};
  c.terminated[1 * 2 + 1] = true;
  const auto r = c.Run();
  EXPECT_THAT(r.advantages, ElementsAre(FloatEq(1.59375f), FloatEq(1.25f),  // t = 0
                                        FloatEq(2.375f), FloatEq(1.0f),     // t = 1
                                        FloatEq(2.5f), FloatEq(2.5f)));     // t = 2
  EXPECT_THAT(r.returns, ElementsAre(FloatEq(2.09375f), FloatEq(1.75f), FloatEq(3.375f),
                                     FloatEq(2.0f), FloatEq(4.0f), FloatEq(4.0f)));
}

TEST(GaeTest, LambdaZeroIsOneStepTd) {
  GaeCase c = BaseCase();
  c.lambda = 0.0f;
  c.truncated[0] = true;
  c.final_values[0] = 6.0f;
  // delta_0 = 1 + 0.5*6 - 0.5 = 3.5 (truncated), delta_1 = 1.75, delta_2 = 2.5
  const auto r = c.Run();
  EXPECT_THAT(r.advantages, ElementsAre(FloatEq(3.5f), FloatEq(1.75f), FloatEq(2.5f)));
  // returns = r_t + gamma * next_value
  EXPECT_THAT(r.returns, ElementsAre(FloatEq(4.0f), FloatEq(2.75f), FloatEq(4.0f)));
}

TEST(GaeTest, LambdaOneIsDiscountedMonteCarloMinusValue) {
  GaeCase c = BaseCase();
  c.lambda = 1.0f;
  c.terminated[2] = true;  // The block ends the episode: values[3] is unused.
  c.values[3] = 1000.0f;
  // G_2 = 3, G_1 = 2 + 0.5*3 = 3.5, G_0 = 1 + 0.5*3.5 = 2.75
  const auto r = c.Run();
  EXPECT_THAT(r.returns, ElementsAre(FloatEq(2.75f), FloatEq(3.5f), FloatEq(3.0f)));
  EXPECT_THAT(r.advantages, ElementsAre(FloatEq(2.25f), FloatEq(2.5f), FloatEq(1.5f)));
}

TEST(GaeTest, LambdaOneMatchesBruteForceReturnsAcrossEpisodes) {
  // A longer block with both kinds of ends, checked against a direct sum:
  // G_t = sum_k gamma^k r_{t+k} up to the episode end, plus the discounted
  // bootstrap (final value at a truncation, values[T] at the block end).
  constexpr int64_t kT = 7;
  GaeCase c(kT, 1);
  c.lambda = 1.0f;
  c.gamma = 0.9f;
  c.rewards = {0.5f, -1, 2, 0.25f, 3, -0.5f, 1};
  c.values = {0.1f, 0.2f, 0.3f, 0.4f, 0.5f, 0.6f, 0.7f, 0.8f};
  c.terminated[2] = true;
  c.truncated[4] = true;
  c.final_values[4] = 5.0f;
  const auto r = c.Run();
  std::vector<float> expected(kT);
  for (int64_t t = 0; t < kT; ++t) {
    double g = 0, discount = 1;
    int64_t k = t;
    for (;; ++k) {
      g += discount * c.rewards[k];
      discount *= c.gamma;
      if (c.terminated[k]) break;
      if (c.truncated[k]) {
        g += discount * c.final_values[k];
        break;
      }
      if (k == kT - 1) {
        g += discount * c.values[kT];
        break;
      }
    }
    expected[t] = static_cast<float>(g);
  }
  EXPECT_THAT(r.returns, Pointwise(::testing::FloatNear(1e-5f), expected));
}


// EDTI's value of interaction with set values, worked by hand: 2 agents,
// c_{0->1} = 0.5, c_{1->0} = -0.25 (agent 1 was less predictable given agent 0).
TEST(EdtiInteractionTest, MatchesTheReleasedRunnersSumWithSetValues) {
  const float influences[4] = {0.0f, 0.5f, -0.25f, 0.0f};  // [i][j]
  const float v_ext[4] = {-1.0f, -1.0f, 100.0f, 200.0f};    // [t+1][agent]: row 1 is read.
  const float v_int[4] = {-1.0f, -1.0f, 3.0f, 5.0f};
  const float r_ext[2] = {0.0f, 1000.0f};
  const float r_int[2] = {10.0f, 7.0f};
  float voi[2];
  EdtiInteractionRewards(1, 1, 2, influences, v_ext, v_int, r_ext, r_int, 0.99f, EdtiCoefficients{}, voi);
  // 0.99 * 0.5 * (0.1 * 200 + 1 * 5) + (0.1 * 1000 + 0.1 * 7)
  EXPECT_NEAR(voi[0], 113.075f, 1e-4f);
  // 0.99 * -0.25 * (0.1 * 100 + 1 * 3) + (0.1 * 0 + 0.1 * 10)
  EXPECT_NEAR(voi[1], -2.2175f, 1e-5f);
  // Without the partner term only the influence-weighted values remain.
  EdtiCoefficients transition_only;
  transition_only.partner = 0.0f;
  EdtiInteractionRewards(1, 1, 2, influences, v_ext, v_int, r_ext, r_int, 0.99f, transition_only, voi);
  EXPECT_NEAR(voi[0], 12.375f, 1e-5f);
}

TEST(EdtiInteractionTest, SumsOverEveryOtherAgentAndStepsAndEnvs) {
  // T = 2, E = 1, n = 3; every influence 1, values V_ext_j = j, V_int = 0, no rewards.
  const int n = 3;
  std::vector<float> influences(2 * n * n, 1.0f), v_ext(3 * n), v_int(3 * n, 0.0f), zeros(2 * n, 0.0f), voi(2 * n);
  for (int t = 0; t < 3; ++t) {
    for (int j = 0; j < n; ++j) v_ext[t * n + j] = static_cast<float>(j + 10 * t);
  }
  EdtiCoefficients coef;
  coef.tv_ext = 1.0f;
  EdtiInteractionRewards(2, 1, n, influences.data(), v_ext.data(), v_int.data(), zeros.data(), zeros.data(), 1.0f,
                         coef, voi.data());
  // Agent i at step t: sum over j != i of V_ext_j(t+1) = (3 * 10(t+1) + 0 + 1 + 2) - (10(t+1) + i).
  for (int t = 0; t < 2; ++t) {
    for (int i = 0; i < n; ++i) EXPECT_FLOAT_EQ(voi[t * n + i], 2 * 10.0f * (t + 1) + 3.0f - i) << t << " " << i;
  }
}

}  // namespace
}  // namespace imca::learner
