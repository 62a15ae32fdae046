#ifndef IMCA_COMMON_BASE_CHECKS_H_
#define IMCA_COMMON_BASE_CHECKS_H_

#include <cmath>
#include <cstdint>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"

namespace imca {

// Checks of an array field of a message or batch (anything with size() and
// operator[]): errors are INVALID_ARGUMENT naming "<what>.<name>" (and the
// element), e.g. "unroll.rewards[3] is not finite".

template <typename Field>
absl::Status CheckSize(absl::string_view what, absl::string_view name, const Field& field, int64_t expected) {
  if (static_cast<int64_t>(field.size()) != expected) {
    return absl::InvalidArgumentError(
        absl::StrCat(what, ".", name, " has ", field.size(), " elements, expected ", expected));
  }
  return absl::OkStatus();
}

template <typename Field>
absl::Status CheckFinite(absl::string_view what, absl::string_view name, const Field& field) {
  for (int64_t i = 0; i < static_cast<int64_t>(field.size()); ++i) {
    if (!std::isfinite(field[i])) {
      return absl::InvalidArgumentError(absl::StrCat(what, ".", name, "[", i, "] is not finite"));
    }
  }
  return absl::OkStatus();
}

}  // namespace imca

#endif  // IMCA_COMMON_BASE_CHECKS_H_
