#include "learner/iteration_metrics.h"

#include <set>
#include <string>
#include <vector>

#include "absl/strings/str_split.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace imca::learner {
namespace {

using ::testing::HasSubstr;

TEST(IterationMetricsTest, TheTableMakesTheHeaderAndRowsOfOneWidth) {
  const std::vector<std::string> header = absl::StrSplit(CsvHeader("mappo", 3), ',');
  ASSERT_EQ(header.size(), RunColumns("mappo").size() + 3);
  EXPECT_EQ(header.front(), "iteration");
  EXPECT_EQ(header.back(), "share_3");
  EXPECT_EQ(std::set<std::string>(header.begin(), header.end()).size(), header.size()) << "a column twice";
  IterationRecord r;
  r.iteration = 7;
  r.env_steps = 14336;
  r.wall_seconds = 1.23456;
  r.wait = 0.0125;  // Seconds, written as ms.
  r.shares = {0.5, 0.25, 0.25};
  r.algorithm = {{"policy_loss", -0.25}, {"clip_fraction", 0.125}};
  const std::vector<std::string> row = absl::StrSplit(CsvRow("mappo", r), ',');
  ASSERT_EQ(row.size(), header.size());
  auto cell = [&](const std::string& name) {
    return row[std::find(header.begin(), header.end(), name) - header.begin()];
  };
  EXPECT_EQ(cell("iteration"), "7");
  EXPECT_EQ(cell("env_steps"), "14336");
  EXPECT_EQ(cell("wall_seconds"), "1.235");
  EXPECT_EQ(cell("ms_wait"), "12.50");
  EXPECT_EQ(cell("share_1"), "0.5000");
  EXPECT_EQ(cell("policy_loss"), "-0.25");
  EXPECT_EQ(cell("clip_fraction"), "0.1250");
  EXPECT_EQ(cell("approx_kl"), "nan");  // An own column the algorithm did not report shows.
}

TEST(IterationMetricsTest, EachAlgorithmHasTheSharedColumnsAndItsOwn) {
  EXPECT_THAT(AlgorithmColumnNames("mappo"), ::testing::ElementsAre("policy_loss", "value_loss", "approx_kl",
                                                                    "clip_fraction", "behaviour_kl", "voi_reward"));
  EXPECT_THAT(AlgorithmColumnNames("maddpg"), ::testing::ElementsAre("actor_loss", "critic_loss", "replay_size"));
  const std::string mappo = CsvHeader("mappo", 2), maddpg = CsvHeader("maddpg", 2);
  EXPECT_THAT(mappo, HasSubstr(",updates,policy_loss,value_loss,approx_kl,clip_fraction,behaviour_kl,voi_reward,"
                               "share_1,share_2"));
  EXPECT_THAT(maddpg, HasSubstr(",updates,actor_loss,critic_loss,replay_size,share_1,share_2"));
  EXPECT_THAT(maddpg, ::testing::Not(HasSubstr("policy_loss")));
  EXPECT_THAT(mappo, ::testing::Not(HasSubstr("actor_loss")));
  // Every column is shared or one algorithm's, and only a shared one reads
  // a member of the record.
  for (const Column& c : IterationColumns()) EXPECT_EQ(c.algorithm.empty(), c.value != nullptr) << c.name;
}

TEST(IterationMetricsTest, ExportedColumnsBecomeFamiliesWithTheirHelp) {
  metrics::Registry registry;
  IterationExporter exporter(&registry, "maddpg");
  IterationRecord r;
  r.iteration = 3;
  r.env_steps = 6144;
  r.updates = 16;
  r.success_rate = 0.75;
  r.algorithm = {{"actor_loss", -1.5}, {"critic_loss", 0.5}, {"replay_size", 4096}};
  exporter.Publish(r);
  r.iteration = 4;
  r.env_steps = 8192;
  exporter.Publish(r);
  const std::string text = registry.Text();
  EXPECT_THAT(text, HasSubstr("# HELP imca_learner_env_steps_total Joint environment steps trained on.\n"
                              "# TYPE imca_learner_env_steps_total counter\nimca_learner_env_steps_total 8192\n"));
  EXPECT_THAT(text, HasSubstr("\nimca_learner_iterations_total 4\n"));
  EXPECT_THAT(text, HasSubstr("\nimca_learner_gradient_steps_total 32\n"));  // Grows by each iteration's.
  EXPECT_THAT(text, HasSubstr("# TYPE imca_learner_eval_success_ratio gauge\nimca_learner_eval_success_ratio 0.75\n"));
  EXPECT_THAT(text, HasSubstr("\nimca_learner_actor_loss -1.5\n"));
  EXPECT_THAT(text, HasSubstr("\nimca_learner_replay_transitions 4096\n"));
  EXPECT_THAT(text, ::testing::Not(HasSubstr("imca_learner_policy_loss")));  // MAPPO's.
  int exported = 0;
  std::set<std::string> families;
  for (const Column& c : RunColumns("maddpg")) {
    EXPECT_EQ(c.exported == Export::kCsvOnly, c.family == nullptr) << c.name;
    if (c.family == nullptr) continue;
    ++exported;
    EXPECT_TRUE(families.insert(c.family).second) << c.family;
    EXPECT_THAT(text, HasSubstr(std::string("# HELP ") + c.family + " " + c.help + "\n"));
  }
  EXPECT_EQ(registry.FamilyNames().size(), exported);
}

}  // namespace
}  // namespace imca::learner
