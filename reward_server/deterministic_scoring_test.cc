// Deterministic scoring (ScorerConfig::deterministic): within a policy
// version the answers and the state a version leaves do not depend on the
// order the actors' calls arrive in, for every reward kind.
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "gtest/gtest.h"
#include "nn/threads.h"
#include "protocol/test_unrolls.h"
#include "reward_server/make_scorer.h"
#include "reward_server/scorer_testing.h"

namespace imca::reward {
namespace {

struct Call {
  std::string actor;
  int64_t sequence;
  int64_t version;
};

struct Answers {
  std::map<std::pair<std::string, int64_t>, std::vector<float>> rewards;  // By (actor, sequence).
  std::string snapshot;                                                   // Save's bytes at the end.
};

class DeterministicScoringTest : public ::testing::TestWithParam<std::tuple<std::string, Credit>> {
 protected:
  void SetUp() override {
    nn::SetTorchThreads(1);
    scenario_ = ::imca::testing::TextScenario("1...\n..T.\n...2\n");
    ASSERT_NE(scenario_, nullptr);
  }

  // Scores `calls` in the order given with a fresh scorer; each call's
  // unroll is drawn from its (actor, sequence), so the same call carries
  // the same transitions in every order.
  Answers Run(const std::vector<Call>& calls, bool deterministic, Permutation permutation = Permutation::kRandom) {
    const auto& [kind, credit] = GetParam();
    ScorerConfig config;
    config.credit = credit;
    config.permutation = permutation;  // Random by default: the random streams too.
    config.deterministic = deterministic;
    auto made = MakeScorer(kind, *scenario_, config);
    EXPECT_TRUE(made.ok()) << made.status();
    std::unique_ptr<CreditScorer> scorer = *std::move(made);
    const int n = scenario_->num_agents();
    Answers answers;
    for (const Call& call : calls) {
      const v1::Unroll u = ::imca::testing::RandomUnroll(
          *scenario_, 16, 2, std::hash<std::string>()(call.actor) * 31 + static_cast<uint64_t>(call.sequence));
      TransitionBatch batch{int64_t{u.length()} * u.num_envs(), u.length(), u.num_envs(), u.state_size(),
                            u.states().data(), u.next_states().data(), u.actions().data(), u.action_probs().data(),
                            u.episode_ids().data(), u.terminated().data(), std::hash<std::string>()(call.actor)};
      batch.actor_id = call.actor;
      batch.sequence = call.sequence;
      batch.policy_version = call.version;
      answers.rewards[{call.actor, call.sequence}] = ::imca::testing::RunScorer(*scorer, batch, n, false).agent_rewards;
    }
    const std::string path = ::testing::TempDir() + "/deterministic_" + std::to_string(getpid()) + ".bin";
    EXPECT_TRUE(scorer->Save(path).ok());
    std::ifstream in(path, std::ios::binary);
    std::stringstream bytes;
    bytes << in.rdbuf();
    answers.snapshot = bytes.str();
    std::remove(path.c_str());
    return answers;
  }

  std::unique_ptr<env::Scenario> scenario_;
};

// Three versions of two actors' two unrolls each, in two interleavings that
// keep each actor's own order (as actors send) but not the actors'.
const std::vector<Call> kForward = {{"a", 1, 1}, {"a", 2, 1}, {"b", 1, 1}, {"b", 2, 1},
                                    {"a", 3, 2}, {"b", 3, 2}, {"a", 4, 2}, {"b", 4, 2},
                                    {"a", 5, 3}, {"a", 6, 3}, {"b", 5, 3}, {"b", 6, 3}};
const std::vector<Call> kBackward = {{"b", 1, 1}, {"a", 1, 1}, {"b", 2, 1}, {"a", 2, 1},
                                     {"b", 3, 2}, {"b", 4, 2}, {"a", 3, 2}, {"a", 4, 2},
                                     {"b", 5, 3}, {"a", 5, 3}, {"a", 6, 3}, {"b", 6, 3}};

TEST_P(DeterministicScoringTest, AnswersAndStateDoNotDependOnArrivalOrder) {
  const Answers forward = Run(kForward, true);
  const Answers backward = Run(kBackward, true);
  ASSERT_EQ(forward.rewards.size(), 12u);
  EXPECT_EQ(forward.rewards, backward.rewards);
  EXPECT_EQ(forward.snapshot, backward.snapshot);
  EXPECT_FALSE(forward.snapshot.empty());
}

TEST_P(DeterministicScoringTest, WithoutItTheOrderShows) {
  // The control: the interleavings above do change what a scorer that
  // applies calls as they come answers.
  EXPECT_NE(Run(kForward, false).rewards, Run(kBackward, false).rewards);
}

TEST_P(DeterministicScoringTest, OneActorOneCallPerVersionIsScoredAsWithoutIt) {
  // Nothing to reorder: the version view and the deferred updates change no
  // answer (the next version's first call applies them before scoring).
  // Without random permutations, whose streams differ by design.
  const std::vector<Call> calls = {{"a", 1, 1}, {"a", 2, 2}, {"a", 3, 3}, {"a", 4, 4}};
  EXPECT_EQ(Run(calls, true, Permutation::kOff).rewards, Run(calls, false, Permutation::kOff).rewards);
}

INSTANTIATE_TEST_SUITE_P(Kinds, DeterministicScoringTest,
                         ::testing::Values(std::make_tuple("count", Credit::kImca),
                                           std::make_tuple("count", Credit::kIndependent),
                                           std::make_tuple("rnd", Credit::kImca),
                                           std::make_tuple("rnd", Credit::kIndependent),
                                           std::make_tuple("sf", Credit::kImca)),
                         [](const auto& info) {
                           return std::get<0>(info.param) + "_" + CreditName(std::get<1>(info.param));
                         });

}  // namespace
}  // namespace imca::reward
