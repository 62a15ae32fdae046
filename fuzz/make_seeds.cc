// Writes the seed corpus of the fuzz targets: serialized real requests (as
// the actor sends them) and the bundled maps. Run once per change of the
// protocol; the output lives in fuzz/corpus/<target>/seed-*.
//   fuzz_seeds OUT_DIR
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "common/env/env.h"
#include "common/protocol/test_unrolls.h"
#include "fuzz/score_kinds.h"
#include "imca/v1/learner_service.pb.h"
#include "imca/v1/reward_service.pb.h"

namespace fs = std::filesystem;
using namespace imca;

namespace {

void Write(const fs::path& path, const std::string& bytes) {
  fs::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary) << bytes;
}

std::unique_ptr<env::Scenario> Scenario(const char* name) {
  env::ScenarioConfig config;
  config.name = name;
  auto scenario = env::MakeScenario(config, env::DefaultMapDir());
  if (!scenario.ok()) {
    std::fprintf(stderr, "%s\n", std::string(scenario.status().message()).c_str());
    std::exit(1);
  }
  return *std::move(scenario);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: fuzz_seeds OUT_DIR\n");
    return 2;
  }
  const fs::path out = argv[1];
  const auto& kinds = fuzz::ScoreKinds();
  for (size_t k = 0; k < kinds.size(); ++k) {
    auto scenario = Scenario(kinds[k].scenario);
    for (int variant = 0; variant < 2; ++variant) {
      v1::ScoreRequest request;
      *request.mutable_unroll() = testing::RandomUnroll(*scenario, 8, 2, 100 * k + variant);
      request.mutable_unroll()->set_actor_id("actor-0");
      request.mutable_unroll()->set_incarnation(0x1234 + variant);
      request.mutable_unroll()->set_sequence(variant);
      request.set_dry_run(variant == 1);
      Write(out / "score" / ("seed-" + std::string(kinds[k].reward) + "-" + kinds[k].scenario + "-" +
                             std::to_string(variant)),
            std::string(1, static_cast<char>(k)) + request.SerializeAsString());
    }
  }
  auto coop_nav = Scenario("coop_nav");
  for (int variant = 0; variant < 3; ++variant) {
    v1::PushUnrollsRequest request;
    v1::Unroll* u = request.mutable_unroll();
    *u = testing::RandomUnroll(*coop_nav, 16, 4, 7 + variant);
    u->set_actor_id("actor-" + std::to_string(variant % 2));
    u->set_incarnation(0x4321);
    u->set_sequence(variant);
    for (int i = 0; i < u->intrinsic_rewards_size(); ++i) u->set_intrinsic_rewards(i, 0.01f * (i % 7));
    Write(out / "push_unrolls" / ("seed-" + std::to_string(variant)), request.SerializeAsString());
  }
  const struct {
    int64_t min_version;
    int wait_ms;
  } policies[] = {{0, 0}, {1, 0}, {0, 100}, {0, -1}, {0, 60001}};
  for (size_t i = 0; i < sizeof(policies) / sizeof(policies[0]); ++i) {
    v1::GetPolicyRequest request;
    request.set_min_version(policies[i].min_version);
    request.set_wait_ms(policies[i].wait_ms);
    Write(out / "get_policy" / ("seed-policy-" + std::to_string(i)), std::string(1, '\0') + request.SerializeAsString());
  }
  Write(out / "get_policy" / "seed-status", std::string(1, '\1') + v1::GetStatusRequest().SerializeAsString());
  for (const auto& entry : fs::directory_iterator(env::DefaultMapDir())) {
    if (entry.path().extension() != ".txt") continue;
    std::ifstream in(entry.path(), std::ios::binary);
    Write(out / "map" / ("seed-" + entry.path().stem().string()),
          std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>()));
  }
  std::printf("seeds written to %s\n", out.c_str());
  return 0;
}
