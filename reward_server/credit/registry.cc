#include "reward_server/credit/registry.h"

namespace imca::reward {

const CreditRuleRegistry& CreditRules() {
  static const CreditRuleRegistry* const kRegistry = new CreditRuleRegistry(BuildRegistry<CreditRuleRegistry>({
#define IMCA_CREDIT_RULE(Prefix) &Register##Prefix,
#include "reward_server/credit/rules.def"
#undef IMCA_CREDIT_RULE
  }));
  return *kRegistry;
}

absl::StatusOr<NoveltyReads> CreditReads(absl::string_view name) {
  absl::StatusOr<const CreditRuleEntry*> rule = CreditRules().Find(name);
  if (!rule.ok()) return rule.status();
  return (*rule)->reads;
}

}  // namespace imca::reward
