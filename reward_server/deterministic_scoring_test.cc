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

#include "common/nn/threads.h"
#include "common/protocol/test_unrolls.h"
#include "gtest/gtest.h"
#include "reward_server/make_scorer.h"
#include "reward_server/scorer_testing.h"

namespace imca::reward {
namespace {

struct Call {
  std::string actor;
  int64_t sequence;
  int64_t version;
  uint64_t incarnation = 1;
};

struct Answers {
  // By (actor, sequence, incarnation): the agent rewards, then the influences (eiti, edti).
  std::map<std::tuple<std::string, int64_t, uint64_t>, std::vector<float>> rewards;
  std::vector<std::vector<float>> in_order;  // The same, in the order scored.
  std::string snapshot;                      // Save's bytes at the end.
};

class DeterministicScoringTest : public ::testing::TestWithParam<std::tuple<std::string, std::string>> {
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
    if (!made.ok()) {
      ADD_FAILURE() << made.status();
      return {};
    }
    std::unique_ptr<CreditScorer> scorer = *std::move(made);
    const int n = scenario_->num_agents();
    Answers answers;
    for (const Call& call : calls) {
      const v1::Unroll u = ::imca::testing::RandomUnroll(
          *scenario_, 16, 2, std::hash<std::string>()(call.actor) * 31 + static_cast<uint64_t>(call.sequence));
      TransitionBatch batch{int64_t{u.length()} * u.num_envs(), u.length(), u.num_envs(), u.state_size(),
                            u.states().data(), u.next_states().data(), u.actions().data(), u.action_probs().data(),
                            u.episode_ids().data(), u.terminated().data(), std::hash<std::string>()(call.actor)};
      // As the service makes it: episodes are per actor incarnation.
      batch.actor = std::hash<std::string>()(call.actor) ^ (call.incarnation * 0x9e3779b97f4a7c15ULL);
      batch.actor_id = call.actor;
      batch.sequence = call.sequence;
      batch.incarnation = call.incarnation;
      batch.policy_version = call.version;
      const int64_t N = batch.size;
      std::vector<float> global(N), contributions(N * n), shares(N * n), rewards(N * n);
      std::vector<float> influences(scorer->ReturnsInfluences() ? N * n * n : 0);
      EXPECT_TRUE(scorer
                      ->Score(batch, false,
                              {global.data(), contributions.data(), shares.data(), rewards.data(),
                               influences.empty() ? nullptr : influences.data()})
                      .ok());
      rewards.insert(rewards.end(), influences.begin(), influences.end());
      answers.rewards[{call.actor, call.sequence, call.incarnation}] = rewards;
      answers.in_order.push_back(std::move(rewards));
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

TEST_P(DeterministicScoringTest, CallsOfOneActorIdAndSequenceAreOrderedByIncarnation) {
  // Two incarnations of one actor id (a restarted actor, or two clients
  // that kept the default id) number their calls alike.
  const Answers forward = Run({{"a", 1, 1, 5}, {"a", 1, 1, 9}, {"a", 2, 2, 5}, {"a", 2, 2, 9}}, true);
  const Answers backward = Run({{"a", 1, 1, 9}, {"a", 1, 1, 5}, {"a", 2, 2, 9}, {"a", 2, 2, 5}}, true);
  EXPECT_EQ(forward.rewards, backward.rewards);
  EXPECT_EQ(forward.snapshot, backward.snapshot);
}

TEST_P(DeterministicScoringTest, AVersionThatGoesBackStartsAVersion) {
  // A learner restarted from an older checkpoint: versions 1, 2, then 1
  // again. The third call sees the first two calls' updates, as the first
  // call of any new version does, and a rerun is the same.
  const std::vector<Call> calls = {{"a", 1, 1}, {"a", 2, 2}, {"a", 3, 1}, {"a", 4, 2}};
  const Answers once = Run(calls, true, Permutation::kOff);
  EXPECT_EQ(once.rewards, Run(calls, true, Permutation::kOff).rewards);
  EXPECT_EQ(once.in_order, Run(calls, false, Permutation::kOff).in_order);
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
                         ::testing::Values(std::make_tuple("count", "imca"),
                                           std::make_tuple("count", "independent"),
                                           std::make_tuple("rnd", "imca"),
                                           std::make_tuple("rnd", "independent"),
                                           std::make_tuple("sf", "imca"),
                                           std::make_tuple("sf", "independent"),
                                           std::make_tuple("eiti", "independent"),
                                           std::make_tuple("edti", "independent")),
                         [](const auto& info) {
                           return std::get<0>(info.param) + "_" + std::get<1>(info.param);
                         });

}  // namespace
}  // namespace imca::reward
