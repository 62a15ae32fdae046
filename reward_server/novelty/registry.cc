#include "reward_server/novelty/registry.h"

#include <cstdio>
#include <cstdlib>
#include <utility>


namespace imca::reward {

namespace {

// Every novelty kind, the first the default: one line each.
NoveltyRegistry Build() {
  NoveltyRegistry registry;
  for (const absl::Status& added : {
           RegisterCount(&registry),
           RegisterRnd(&registry),
           RegisterSf(&registry),
           RegisterInfluence(&registry),
       }) {
    if (!added.ok()) {  // A programming error: fail at the first use, loudly.
      std::fprintf(stderr, "reward_server: novelty registry: %s\n", std::string(added.message()).c_str());
      std::abort();
    }
  }
  return registry;
}

}  // namespace

const NoveltyRegistry& Novelties() {
  static const NoveltyRegistry* const kRegistry = new NoveltyRegistry(Build());
  return *kRegistry;
}

}  // namespace imca::reward
