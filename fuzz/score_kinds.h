#ifndef IMCA_FUZZ_SCORE_KINDS_H_
#define IMCA_FUZZ_SCORE_KINDS_H_

#include <vector>

#include "reward_server/credit.h"

namespace imca::fuzz {

// The reward servers score_fuzzer serves, picked by an input's first byte
// (the seeds use the same table).
struct ScoreKind {
  const char* scenario;
  const char* reward;
  std::string credit;
};

inline const std::vector<ScoreKind>& ScoreKinds() {
  static const std::vector<ScoreKind> kinds = {
      {"coop_nav", "count", "imca"},
      {"coop_nav", "count", "shared"},
      {"predator_prey", "count", "none"},
      {"pass", "eiti", "independent"},
      {"secret_room", "edti", "independent"},
      {"twin_buttons", "rnd", "imca"},
      {"multi_room", "sf", "imca"},
  };
  return kinds;
}

}  // namespace imca::fuzz

#endif  // IMCA_FUZZ_SCORE_KINDS_H_
