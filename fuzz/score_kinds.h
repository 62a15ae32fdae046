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
  reward::Credit credit;
};

inline const std::vector<ScoreKind>& ScoreKinds() {
  static const std::vector<ScoreKind> kinds = {
      {"coop_nav", "count", reward::Credit::kImca},
      {"coop_nav", "count", reward::Credit::kShared},
      {"predator_prey", "count", reward::Credit::kNone},
      {"pass", "eiti", reward::Credit::kIndependent},
      {"secret_room", "edti", reward::Credit::kIndependent},
      {"twin_buttons", "rnd", reward::Credit::kImca},
      {"multi_room", "sf", reward::Credit::kImca},
  };
  return kinds;
}

}  // namespace imca::fuzz

#endif  // IMCA_FUZZ_SCORE_KINDS_H_
