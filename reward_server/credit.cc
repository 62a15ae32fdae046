#include "reward_server/credit.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"

namespace imca::reward {

absl::StatusOr<Credit> ParseCredit(absl::string_view name) {
  if (name == "none") return Credit::kNone;
  if (name == "independent") return Credit::kIndependent;
  if (name == "shared") return Credit::kShared;
  if (name == "imca") return Credit::kImca;
  return absl::InvalidArgumentError(
      absl::StrCat("credit '", name, "' is not one of none|independent|shared|imca"));
}

absl::StatusOr<Permutation> ParsePermutation(absl::string_view name) {
  if (name == "off") return Permutation::kOff;
  if (name == "random") return Permutation::kRandom;
  if (name == "canonical") return Permutation::kCanonical;
  return absl::InvalidArgumentError(
      absl::StrCat("permutation '", name, "' is not one of off|random|canonical"));
}

absl::string_view CreditName(Credit credit) {
  switch (credit) {
    case Credit::kNone: return "none";
    case Credit::kIndependent: return "independent";
    case Credit::kShared: return "shared";
    case Credit::kImca: return "imca";
  }
  return "?";
}

absl::string_view PermutationName(Permutation permutation) {
  switch (permutation) {
    case Permutation::kOff: return "off";
    case Permutation::kRandom: return "random";
    case Permutation::kCanonical: return "canonical";
  }
  return "?";
}

void SoftmaxShares(const float* contributions, int n, double temperature, float* shares) {
  double max = contributions[0] / temperature;
  for (int a = 1; a < n; ++a) max = std::max(max, contributions[a] / temperature);
  double sum = 0;
  for (int a = 0; a < n; ++a) sum += std::exp(contributions[a] / temperature - max);
  for (int a = 0; a < n; ++a) {
    shares[a] = static_cast<float>(std::exp(contributions[a] / temperature - max) / sum);
  }
}

}  // namespace imca::reward
