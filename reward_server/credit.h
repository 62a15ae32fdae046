#ifndef IMCA_REWARD_SERVER_CREDIT_H_
#define IMCA_REWARD_SERVER_CREDIT_H_

#include <cstdint>
#include <string>
#include <vector>

#include "absl/strings/string_view.h"

#include "absl/status/statusor.h"

namespace imca::reward {

// How a global bonus becomes per-agent bonuses (docs/credit.md).
enum class Credit { kNone, kIndependent, kShared, kImca };
// How homogeneous agents' identities enter keys (docs/credit.md, paper 4.3).
enum class Permutation { kOff, kRandom, kCanonical };

// Parse "none|independent|shared|imca" and "off|random|canonical".
// Errors: INVALID_ARGUMENT naming the value and the choices.
absl::StatusOr<Credit> ParseCredit(absl::string_view name);
absl::StatusOr<Permutation> ParsePermutation(absl::string_view name);
std::string CreditName(Credit credit);
std::string PermutationName(Permutation permutation);
// Every credit and permutation mode's name (reward_server --list).
std::vector<std::string> CreditNames();
std::vector<std::string> PermutationNames();

struct ScorerConfig {
  Credit credit = Credit::kImca;
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
};

// p^a = softmax_a(r^a / tau) over n contributions (numerically stable).
void SoftmaxShares(const float* contributions, int n, double temperature, float* shares);

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_CREDIT_H_
