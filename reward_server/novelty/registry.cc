#include "reward_server/novelty/registry.h"

namespace imca::reward {

const NoveltyRegistry& Novelties() {
  static const NoveltyRegistry* const kRegistry = new NoveltyRegistry(BuildRegistry<NoveltyRegistry>({
#define IMCA_NOVELTY(Prefix) &Register##Prefix,
#include "reward_server/novelty/novelties.def"
#undef IMCA_NOVELTY
  }));
  return *kRegistry;
}

}  // namespace imca::reward
