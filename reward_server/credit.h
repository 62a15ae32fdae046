#ifndef IMCA_REWARD_SERVER_CREDIT_H_
#define IMCA_REWARD_SERVER_CREDIT_H_

#include <cstdint>
#include <string>
#include <vector>

#include "absl/strings/string_view.h"

#include "absl/status/statusor.h"

namespace imca::reward {

// How homogeneous agents' identities enter keys (docs/credit.md, paper 4.3).
enum class Permutation { kOff, kRandom, kCanonical };

// Parse "off|random|canonical". Errors: INVALID_ARGUMENT naming the value
// and the choices.
absl::StatusOr<Permutation> ParsePermutation(absl::string_view name);
std::string PermutationName(Permutation permutation);
// Every permutation mode's name (reward_server --list).
std::vector<std::string> PermutationNames();
// Their flag spelling, the names above (common/base/settings.h).
std::vector<std::string> SettingChoices(Permutation);
bool AbslParseFlag(absl::string_view text, Permutation* permutation, std::string* error);
std::string AbslUnparseFlag(Permutation permutation);

struct ScorerConfig {
  // The credit rule (credit/rules.def): how the global bonus becomes
  // per-agent bonuses.
  std::string credit = "imca";
  Permutation permutation = Permutation::kOff;
  double beta = 1.0;         // Coefficient of the global bonus.
  double temperature = 1.0;  // tau of the softmax over contributions.
  uint64_t seed = 1;         // For the random permutation mode.
  // Deterministic scoring (docs/credit.md, "Deterministic runs"): every
  // call of one policy version sees the state as the version's first call
  // found it plus its own batch's updates, and the updates of a version
  // reach the state in (actor id, sequence) order, whatever order the calls
  // came in. Count kinds then draw a call's random permutations from its
  // own stream (NamedSeed(seed, actor id, sequence)); learned kinds draw
  // theirs as the deferred updates run, in that order.
  bool deterministic = false;
  // LibTorch intra-op threads of the process, for the learned kinds (rnd,
  // sf); set once per process (common/nn/threads.h).
  int threads = 1;
};

// The settings every reward kind shares (common/base/settings.h): type, flag,
// field of ScorerConfig, help. A kind's own are its registry entry's
// (novelty/registry.h); --credit's choices are the credit rules'
// (reward_flags.cc).
#define IMCA_SCORER_SETTINGS(X)                                                                                     \
  X(::imca::reward::Permutation, permutation, permutation, "permutation mode of homogeneous agents' keys")         \
  X(double, beta, beta, "coefficient of the global intrinsic reward")                                               \
  X(double, temperature, temperature, "softmax temperature tau of the credit shares")                               \
  X(uint64_t, seed, seed, "seed of the random permutation mode")                                                    \
  X(bool, deterministic, deterministic,                                                                             \
    "score each policy version's calls against the state its first call found, applying the version's updates in " \
    "(actor id, sequence) order: with the learner's --deterministic, a run is a function of its configuration")    \
  X(int, threads, threads, "LibTorch intra-op threads (rnd, sf)")

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_CREDIT_H_
