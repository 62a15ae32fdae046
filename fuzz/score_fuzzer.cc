// Fuzzes the reward server's request handling in-process: bytes -> a parsed
// ScoreRequest -> RewardServiceImpl::Score (validation, the scorer, the
// tables) for the reward kind the first byte picks. Invariants beyond "no
// crash": an answer has the documented sizes and only finite values; a
// refused request counts nothing (docs/security.md, "nothing half-applied").
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "common/env/env.h"
#include "fuzz/fuzz_check.h"
#include "fuzz/score_kinds.h"
#include "google/protobuf/stubs/logging.h"
#include "imca/v1/reward_service.pb.h"
#include "reward_server/make_scorer.h"
#include "reward_server/reward_service.h"

namespace {

using namespace imca;

struct Served {
  std::unique_ptr<env::Scenario> scenario;
  std::unique_ptr<reward::Scorer> scorer;
  std::unique_ptr<reward::RewardServiceImpl> service;
};

std::vector<Served>* services = nullptr;

bool AllFinite(const google::protobuf::RepeatedField<float>& values) {
  for (float v : values) {
    if (!std::isfinite(v)) return false;
  }
  return true;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  // Mutated strings are often not UTF-8: protobuf would log each one.
  google::protobuf::SetLogHandler(nullptr);
  services = new std::vector<Served>();
  for (const fuzz::ScoreKind& kind : fuzz::ScoreKinds()) {
    Served s;
    env::ScenarioConfig config;
    config.name = kind.scenario;
    auto scenario = env::MakeScenario(config, env::DefaultMapDir());
    FUZZ_CHECK(scenario.ok());
    s.scenario = *std::move(scenario);
    reward::ScorerConfig scorer_config;
    scorer_config.credit = kind.credit;
    auto scorer = reward::MakeScorer(kind.reward, *s.scenario, scorer_config);
    FUZZ_CHECK(scorer.ok());
    s.scorer = *std::move(scorer);
    s.service = std::make_unique<reward::RewardServiceImpl>(s.scenario.get(), s.scorer.get(), kind.reward,
                                                            scorer_config, "");
    services->push_back(std::move(s));
  }
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  Served& s = (*services)[data[0] % services->size()];
  v1::ScoreRequest request;
  if (!request.ParseFromArray(data + 1, static_cast<int>(size - 1))) return 0;
  const int64_t before = s.service->Stats().transitions_scored();
  grpc::ServerContext context;
  v1::ScoreResponse response;
  const grpc::Status status = s.service->Score(&context, &request, &response);
  const int64_t after = s.service->Stats().transitions_scored();
  if (!status.ok()) {
    FUZZ_CHECK(after == before);
    return 0;
  }
  const v1::Unroll& u = request.unroll();
  const int64_t count = int64_t{u.length()} * u.num_envs();
  const int n = u.num_agents();
  FUZZ_CHECK(response.num_transitions() == count && response.num_agents() == n);
  FUZZ_CHECK(response.global_rewards_size() == count);
  FUZZ_CHECK(response.agent_rewards_size() == count * n && response.shares_size() == count * n &&
             response.contributions_size() == count * n);
  FUZZ_CHECK(AllFinite(response.agent_rewards()) && AllFinite(response.shares()) &&
             AllFinite(response.global_rewards()) && AllFinite(response.contributions()) &&
             AllFinite(response.influences()));
  FUZZ_CHECK(after == before || after == before + count);
  if (request.dry_run()) FUZZ_CHECK(after == before);
  return 0;
}
