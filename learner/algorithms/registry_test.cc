#include "learner/algorithms/registry.h"

#include <memory>
#include <set>
#include <string>

#include "absl/flags/flag.h"
#include "common/base/status_macros.h"
#include "common/env/env.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "learner/algorithms/acting.h"
#include "learner/learner_flags.h"

// A toy algorithm, whole: its options and their one table of settings, its
// Algorithm, its entry. Adding it to the learner is this much plus one line
// in algorithms.def (and its sources in learner/CMakeLists.txt).
namespace imca::learner {
namespace {

struct ToyOptions {
  double rate = 0.25;
  int rounds = 3;
};
#define IMCA_TOY_SETTINGS(X)                     \
  X(double, toy_rate, rate, "toy: a rate")       \
  X(int, toy_rounds, rounds, "toy: some rounds")

}  // namespace
}  // namespace imca::learner

IMCA_TOY_SETTINGS(IMCA_SETTING_FLAG)

namespace imca::learner {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;

IMCA_SETTING_TABLE(ToySettings, ToyOptions, IMCA_TOY_SETTINGS)

// Counts what it is given; trains nothing.
class Toy final : public Algorithm {
 public:
  static absl::StatusOr<std::unique_ptr<Toy>> Create(const env::Scenario*, const LearnerConfig& config) {
    IMCA_ASSIGN_OR_RETURN(const ToyOptions* options, CheckedOptions<ToyOptions>(config));
    return std::unique_ptr<Toy>(new Toy(*options));
  }
  FeaturisedUnroll Featurise(v1::Unroll unroll) const override { return {std::move(unroll), {}, {}, 0}; }
  int64_t IterationBytes(int64_t) const override { return 0; }
  absl::Status Add(const FeaturisedUnroll& unroll) override {
    steps_ += unroll.unroll.length() * unroll.unroll.num_envs();
    return absl::OkStatus();
  }
  absl::StatusOr<IterationStats> Train() override {
    IterationStats stats;
    stats.values = {{"toy_steps", static_cast<double>(steps_) * options_.rate}};
    return stats;
  }
  v1::Policy ExportPolicy(int64_t version) const override {
    v1::Policy policy;
    policy.set_version(version);
    return policy;
  }
  absl::Status Save(const std::string&) const override { return absl::OkStatus(); }
  absl::Status Load(const std::string&) override { return absl::OkStatus(); }

 private:
  explicit Toy(const ToyOptions& options) : options_(options) {}
  const ToyOptions options_;
  int64_t steps_ = 0;
};

// Its whole registration: what a toy_registration.cc would hold.
AlgorithmEntry ToyEntry() {
  return MakeAlgorithmEntry<Toy>(
      "toy", "a toy: counts steps", ToySettings(),
      [](absl::string_view, LearnerConfig* config) { MutableOptions<ToyOptions>(config).rounds = 5; },
      {{"toy_steps", "%.0f", 1, "Steps the toy was given, times its rate.", nullptr, Export::kCsvOnly, nullptr}});
}

TEST(AlgorithmRegistryTest, ATakenNameOrAMissingHookIsRefused) {
  AlgorithmRegistry registry;
  ASSERT_TRUE(registry.Add(ToyEntry()).ok());
  EXPECT_THAT(std::string(registry.Add(ToyEntry()).message()), HasSubstr("'toy' is registered twice"));
  AlgorithmEntry nameless = ToyEntry();
  nameless.name = "";
  EXPECT_THAT(std::string(registry.Add(nameless).message()), HasSubstr("needs a name"));
  AlgorithmEntry hookless = ToyEntry();
  hookless.name = "toy2";
  hookless.create = nullptr;
  EXPECT_THAT(std::string(registry.Add(hookless).message()), HasSubstr("lacks a hook"));
  EXPECT_THAT(registry.Names(), ElementsAre("toy"));
}

TEST(AlgorithmRegistryTest, TheToyArrivesWithItsSettingsColumnsAndFactory) {
  AlgorithmRegistry registry;
  ASSERT_TRUE(registry.Add(ToyEntry()).ok());
  const AlgorithmEntry& toy = **registry.Find("toy");
  EXPECT_EQ((*registry.Find(""))->name, "toy");  // The first is the default.
  ASSERT_EQ(toy.settings.size(), 2u);
  EXPECT_EQ(toy.settings[0].name, "toy_rate");
  EXPECT_EQ(toy.settings[0].type, "float");
  EXPECT_EQ(toy.settings[1].owner, "toy");
  EXPECT_EQ(toy.columns[0].algorithm, "toy");

  LearnerConfig config;
  toy.defaults("coop_nav", &config);
  absl::SetFlag(&FLAGS_toy_rate, 0.5);
  ASSERT_TRUE(toy.fill_from_flags(&config).ok());
  absl::SetFlag(&FLAGS_toy_rate, std::nullopt);
  JsonObject json;
  toy.add_json(config, &json);
  EXPECT_EQ(json.Text(), R"({"toy_rate": 0.5, "toy_rounds": 5})");

  auto algorithm = toy.create(nullptr, config);
  ASSERT_TRUE(algorithm.ok()) << algorithm.status();
  v1::Unroll unroll;
  unroll.set_length(4);
  unroll.set_num_envs(2);
  ASSERT_TRUE((*algorithm)->Add((*algorithm)->Featurise(unroll)).ok());
  EXPECT_EQ((*algorithm)->Train()->values[0].second, 4.0);

  LearnerConfig other;
  other.options = 7;  // Another algorithm's options.
  EXPECT_THAT(std::string(toy.create(nullptr, other).status().message()), HasSubstr("another algorithm's options"));
}

TEST(AlgorithmRegistryTest, AnUnknownNameIsRefusedNamingTheKnownOnes) {
  absl::StatusOr<const AlgorithmEntry*> found = Algorithms().Find("ppo");
  ASSERT_FALSE(found.ok());
  EXPECT_EQ(found.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(found.status().message()), HasSubstr("--algo: 'ppo' is not mappo, maddpg or cmae"));
  EXPECT_FALSE(DefaultLearnerConfig("coop_nav", "ppo").ok());
}

// Flags are process-wide: no two settings may share a name, and each
// algorithm's rows and columns carry its name.
TEST(AlgorithmRegistryTest, EverySettingHasOneNameAndEveryEntryOwnsItsRowsAndColumns) {
  std::set<std::string> names;
  for (const SettingRow& row : LearnerSettingRows()) {
    EXPECT_TRUE(names.insert(row.name).second) << row.name << " is declared twice";
    EXPECT_FALSE(row.help.empty()) << row.name;
  }
  for (const AlgorithmEntry& entry : Algorithms().entries()) {
    for (const SettingRow& row : entry.settings) EXPECT_EQ(row.owner, entry.name) << row.name;
    for (const Column& column : entry.columns) EXPECT_EQ(column.algorithm, entry.name) << column.name;
  }
}

// The actors' list (algorithms.def, torch-free) is the learner's.
TEST(AlgorithmRegistryTest, TheActorsKnowTheSameAlgorithms) {
  std::vector<std::string> acting;
  for (const AlgorithmActing& a : AlgorithmsActing()) acting.push_back(a.name);
  EXPECT_EQ(acting, Algorithms().Names());
}

// Each algorithm's defaults resolve on every scenario and print every
// setting of the algorithm's.
TEST(AlgorithmRegistryTest, EveryAlgorithmsDefaultsResolveOnEveryScenario) {
  for (const AlgorithmEntry& entry : Algorithms().entries()) {
    for (const std::string& scenario : env::ScenarioNames()) {
      absl::StatusOr<LearnerConfig> config = DefaultLearnerConfig(scenario, entry.name);
      ASSERT_TRUE(config.ok()) << entry.name << " on " << scenario << ": " << config.status();
      EXPECT_EQ(config->algo, entry.name);
      const std::string json = LearnerConfigJson(*config);
      for (const SettingRow& row : entry.settings) {
        EXPECT_THAT(json, HasSubstr("\"" + row.name + "\": ")) << entry.name << " on " << scenario;
      }
    }
  }
}

}  // namespace
}  // namespace imca::learner
