#ifndef IMCA_COMMON_BASE_JSON_H_
#define IMCA_COMMON_BASE_JSON_H_

#include <cstdint>
#include <cstdlib>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/string_view.h"

namespace imca {

// `text` as a JSON string literal, quoted and escaped. Pure.
inline std::string JsonString(absl::string_view text) {
  std::string out = "\"";
  for (const char c : text) {
    if (c == '"' || c == '\\') {
      absl::StrAppend(&out, "\\", std::string(1, c));
    } else if (static_cast<unsigned char>(c) < 0x20) {
      absl::StrAppend(&out, absl::StrFormat("\\u%04x", c));
    } else {
      out += c;
    }
  }
  return out + "\"";
}

// `items` as a JSON array of strings. Pure.
inline std::string JsonStrings(const std::vector<std::string>& items) {
  std::string out = "[";
  for (size_t i = 0; i < items.size(); ++i) absl::StrAppend(&out, i > 0 ? ", " : "", JsonString(items[i]));
  return out + "]";
}

// The shortest decimal that parses back to `value` (finite values): whole
// numbers as integers, others by the fewest %g digits that round-trip (as a
// float, for a float).
template <typename T>
std::string ExactNumber(T value) {
  if (value < T(1e15) && value > T(-1e15) && value == static_cast<T>(static_cast<int64_t>(value))) {
    return absl::StrCat(static_cast<int64_t>(value));
  }
  for (int digits = 1; digits < 17; ++digits) {
    std::string text = absl::StrFormat("%.*g", digits, static_cast<double>(value));
    if (static_cast<T>(std::strtod(text.c_str(), nullptr)) == value) return text;
  }
  return absl::StrFormat("%.17g", static_cast<double>(value));
}

// Builds one JSON object, keys in the order added: what the binaries print
// for --list and --print_config. Not thread-safe.
class JsonObject {
 public:
  JsonObject& Add(absl::string_view key, absl::string_view value) { return Raw(key, JsonString(value)); }
  JsonObject& Add(absl::string_view key, const char* value) { return Raw(key, JsonString(value)); }
  JsonObject& Add(absl::string_view key, bool value) { return Raw(key, value ? "true" : "false"); }
  JsonObject& Add(absl::string_view key, int64_t value) { return Raw(key, absl::StrCat(value)); }
  JsonObject& Add(absl::string_view key, int value) { return Raw(key, absl::StrCat(value)); }
  // `digits` after the point (e.g. 3 for a time in ms resolution).
  JsonObject& Add(absl::string_view key, double value, int digits) {
    return Raw(key, absl::StrFormat("%.*f", digits, value));
  }
  JsonObject& Add(absl::string_view key, uint64_t value) { return Raw(key, absl::StrCat(value)); }
  // The shortest decimal that reads back as exactly `value` (a flag value
  // printed by --print_config passes back unchanged).
  JsonObject& AddExact(absl::string_view key, double value) { return Raw(key, ExactNumber(value)); }
  JsonObject& AddExact(absl::string_view key, float value) { return Raw(key, ExactNumber(value)); }
  JsonObject& Add(absl::string_view key, const std::vector<std::string>& values) {
    return Raw(key, JsonStrings(values));
  }
  // `json`: an already formatted JSON value (an object or array).
  JsonObject& Raw(absl::string_view key, absl::string_view json) {
    absl::StrAppend(&text_, text_.empty() ? "{" : ", ", JsonString(key), ": ", json);
    return *this;
  }
  // The object (one line).
  std::string Text() const { return text_.empty() ? "{}" : text_ + "}"; }

 private:
  std::string text_;
};

}  // namespace imca

#endif  // IMCA_COMMON_BASE_JSON_H_
