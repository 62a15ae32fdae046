#ifndef IMCA_FUZZ_FUZZ_LEARNER_H_
#define IMCA_FUZZ_FUZZ_LEARNER_H_

#include <memory>

#include "common/env/env.h"
#include "fuzz/fuzz_check.h"
#include "learner/algorithms/mappo/mappo_options.h"
#include "learner/learner.h"

namespace imca::fuzz {

// A small MAPPO learner on coop_nav (hidden 8, no checkpoints) for the
// learner targets, made once and kept for the life of the process (as a
// server keeps its own).
inline learner::Learner* FuzzLearner(int batch_steps = learner::LearnerConfig{}.batch_steps) {
  static env::Scenario* scenario = [] {
    auto made = env::MakeScenario(env::ScenarioConfig{}, env::DefaultMapDir());
    FUZZ_CHECK(made.ok());
    return made->release();
  }();
  learner::LearnerConfig config;
  config.batch_steps = batch_steps;
  config.budget_steps = int64_t{1} << 50;
  config.checkpoint_every = 0;
  config.checkpoint_seconds = 0;
  learner::MutableOptions<learner::MappoOptions>(&config).ppo.hidden = 8;
  auto created = learner::Learner::Create(scenario, config);
  FUZZ_CHECK(created.ok());
  return created->release();
}

}  // namespace imca::fuzz

#endif  // IMCA_FUZZ_FUZZ_LEARNER_H_
