#include "reward_server/credit.h"

#include "absl/strings/str_cat.h"
#include "common/base/enum_names.h"
#include "reward_server/scorer.h"

namespace imca::reward {

namespace {

constexpr EnumName<Permutation> kPermutationNames[] = {
    {Permutation::kOff, "off"}, {Permutation::kRandom, "random"}, {Permutation::kCanonical, "canonical"}};
constexpr EnumName<ScorePhase> kScorePhaseNames[] = {
    {ScorePhase::kLockWait, "lock_wait"}, {ScorePhase::kEncode, "encode"},
    {ScorePhase::kNovelty, "novelty"},    {ScorePhase::kCounterfactual, "counterfactual"},
    {ScorePhase::kTrain, "train"},        {ScorePhase::kCredit, "credit"}};
static_assert(sizeof(kScorePhaseNames) / sizeof(kScorePhaseNames[0]) == kNumScorePhases);

}  // namespace

absl::StatusOr<Permutation> ParsePermutation(absl::string_view name) {
  return ParseName(std::string(name), kPermutationNames);
}
std::string PermutationName(Permutation permutation) { return NameOf(permutation, kPermutationNames); }
std::vector<std::string> SettingChoices(Permutation) { return Names(kPermutationNames); }
bool AbslParseFlag(absl::string_view text, Permutation* permutation, std::string* error) {
  return ParseFlagName(text, kPermutationNames, permutation, error);
}
std::string AbslUnparseFlag(Permutation permutation) { return PermutationName(permutation); }
std::vector<std::string> PermutationNames() { return Names(kPermutationNames); }
std::string ScorePhaseName(ScorePhase phase) { return NameOf(phase, kScorePhaseNames); }

}  // namespace imca::reward
