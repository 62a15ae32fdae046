#ifndef IMCA_COMMON_BASE_ENUM_NAMES_H_
#define IMCA_COMMON_BASE_ENUM_NAMES_H_

#include <cstddef>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"

namespace imca {

// One row of an enum's name table: the flag and file spelling of a value.
template <typename E>
struct EnumName {
  E value;
  const char* name;
};

// The name of `value` in `names` ("" if it has none). Pure.
template <typename E, size_t N>
std::string NameOf(E value, const EnumName<E> (&names)[N]) {
  for (const EnumName<E>& n : names) {
    if (n.value == value) return n.name;
  }
  return "";
}

// The value named `text`. Errors: INVALID_ARGUMENT "'x' is not a, b or c".
template <typename E, size_t N>
absl::StatusOr<E> ParseName(const std::string& text, const EnumName<E> (&names)[N]) {
  std::string choices;
  for (size_t i = 0; i < N; ++i) {
    if (text == names[i].name) return names[i].value;
    absl::StrAppend(&choices, i == 0 ? "" : (i + 1 == N ? " or " : ", "), names[i].name);
  }
  return absl::InvalidArgumentError(absl::StrCat("'", text, "' is not ", choices));
}

// AbslParseFlag of an enum by its name table: false with `error` naming the
// accepted values.
template <typename E, size_t N>
bool ParseFlagName(absl::string_view text, const EnumName<E> (&names)[N], E* value, std::string* error) {
  absl::StatusOr<E> parsed = ParseName(std::string(text), names);
  if (!parsed.ok()) {
    *error = std::string(parsed.status().message());
    return false;
  }
  *value = *parsed;
  return true;
}

// Every name of `names`, in order (what `--list` prints).
template <typename E, size_t N>
std::vector<std::string> Names(const EnumName<E> (&names)[N]) {
  std::vector<std::string> out;
  for (const EnumName<E>& n : names) out.push_back(n.name);
  return out;
}

}  // namespace imca

#endif  // IMCA_COMMON_BASE_ENUM_NAMES_H_
