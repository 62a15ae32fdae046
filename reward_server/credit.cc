#include "reward_server/credit.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "base/enum_names.h"
#include "reward_server/scorer.h"

namespace imca::reward {

namespace {

constexpr EnumName<Credit> kCreditNames[] = {{Credit::kNone, "none"},
                                             {Credit::kIndependent, "independent"},
                                             {Credit::kShared, "shared"},
                                             {Credit::kImca, "imca"}};
constexpr EnumName<Permutation> kPermutationNames[] = {
    {Permutation::kOff, "off"}, {Permutation::kRandom, "random"}, {Permutation::kCanonical, "canonical"}};
constexpr EnumName<ScorePhase> kScorePhaseNames[] = {
    {ScorePhase::kLockWait, "lock_wait"}, {ScorePhase::kEncode, "encode"},
    {ScorePhase::kNovelty, "novelty"},    {ScorePhase::kCounterfactual, "counterfactual"},
    {ScorePhase::kTrain, "train"},        {ScorePhase::kCredit, "credit"}};
static_assert(sizeof(kScorePhaseNames) / sizeof(kScorePhaseNames[0]) == kNumScorePhases);

}  // namespace

absl::StatusOr<Credit> ParseCredit(absl::string_view name) { return ParseName(std::string(name), kCreditNames); }
absl::StatusOr<Permutation> ParsePermutation(absl::string_view name) {
  return ParseName(std::string(name), kPermutationNames);
}
std::string CreditName(Credit credit) { return NameOf(credit, kCreditNames); }
std::string PermutationName(Permutation permutation) { return NameOf(permutation, kPermutationNames); }
std::vector<std::string> CreditNames() { return Names(kCreditNames); }
std::vector<std::string> SettingChoices(Credit) { return Names(kCreditNames); }
std::vector<std::string> SettingChoices(Permutation) { return Names(kPermutationNames); }
bool AbslParseFlag(absl::string_view text, Credit* credit, std::string* error) {
  return ParseFlagName(text, kCreditNames, credit, error);
}
bool AbslParseFlag(absl::string_view text, Permutation* permutation, std::string* error) {
  return ParseFlagName(text, kPermutationNames, permutation, error);
}
std::string AbslUnparseFlag(Credit credit) { return CreditName(credit); }
std::string AbslUnparseFlag(Permutation permutation) { return PermutationName(permutation); }
std::vector<std::string> PermutationNames() { return Names(kPermutationNames); }
std::string ScorePhaseName(ScorePhase phase) { return NameOf(phase, kScorePhaseNames); }

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
