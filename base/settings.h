#ifndef IMCA_BASE_SETTINGS_H_
#define IMCA_BASE_SETTINGS_H_

// A configuration's settings, each declared once. Beside a config struct, a
// table of rows as an X-macro:
//
//   #define IMCA_FOO_SETTINGS(X)                                   \
//     X(int, epochs, epochs, "PPO epochs per iteration")           \
//     X(double, lr, ppo.learning_rate, "Adam learning rate")
//
// A row is (type, name, field, help): the value's type, the name of its flag
// and of its key in --print_config and --list, the field it sets (a member
// path inside the config), and one line of help. One `*_flags.cc` expands
// the table with the macros below into everything a setting is spelled as:
//   IMCA_SETTING_FLAG  the flag, std::optional<type> (given or not: a
//                      setting not given keeps the config's default, which
//                      may be the scenario's or the algorithm's);
//   IMCA_SETTING_FILL  `config->field = flag` for each flag given;
//   IMCA_SETTING_JSON  `"name": value` (what --print_config prints; passed
//                      back as flags, it resolves to the same config);
//   IMCA_SETTING_ROW   {name, type, help, choices} (what --list prints, and
//                      the launcher's options are read from).
// An enum type is a setting type when its namespace declares, for ADL,
// AbslParseFlag / AbslUnparseFlag (its flag spelling) and
// `std::vector<std::string> SettingChoices(E)` (every name, in order).
// Booleans take the bare form (--x, --nox) as well as --x=true|false: call
// BareBooleanFlags on argv before absl::ParseCommandLine.

#include <cstdint>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/strings/string_view.h"
#include "base/json.h"

namespace imca {

// One setting as --list prints it.
struct SettingRow {
  std::string name;
  std::string type;  // "bool", "int", "float", "string" or "enum".
  std::string help;
  std::vector<std::string> choices;  // An enum's names; empty otherwise.
  // The family member it belongs to (an --algo name, say), or "" for all.
  std::string owner;
};

template <typename T>
SettingRow MakeSettingRow(const char* name, const char* help) {
  SettingRow row{name, "", help, {}, ""};
  if constexpr (std::is_same_v<T, bool>) {
    row.type = "bool";
  } else if constexpr (std::is_integral_v<T>) {
    row.type = "int";
  } else if constexpr (std::is_floating_point_v<T>) {
    row.type = "float";
  } else if constexpr (std::is_enum_v<T>) {
    row.type = "enum";
    row.choices = SettingChoices(T{});
  } else {
    static_assert(std::is_same_v<T, std::string>, "a setting is a bool, number, enum or string");
    row.type = "string";
  }
  return row;
}

// Adds `"name": value` to `json` in the spelling its flag reads back.
template <typename T>
void AddSetting(JsonObject* json, absl::string_view name, const T& value) {
  if constexpr (std::is_same_v<T, bool>) {
    json->Add(name, value);
  } else if constexpr (std::is_same_v<T, uint64_t>) {
    json->Add(name, value);
  } else if constexpr (std::is_integral_v<T>) {
    json->Add(name, static_cast<int64_t>(value));
  } else if constexpr (std::is_floating_point_v<T>) {
    json->AddExact(name, value);
  } else if constexpr (std::is_enum_v<T>) {
    json->Add(name, AbslUnparseFlag(value));
  } else {
    json->Add(name, absl::string_view(value));
  }
}

// `rows` as a JSON array of {"name", "type", "help", "choices", "owner"}.
std::string SettingRowsJson(const std::vector<SettingRow>& rows);

// argv with every bare boolean flag of `names` spelled out for absl, which
// reads an optional<bool> flag's value from the next argument: --x and -x
// become --x=true, --nox and -nox --x=false; the rest, and everything after
// "--", is as given. Pass ArgvOf(the result) to absl::ParseCommandLine.
std::vector<std::string> BareBooleanFlags(int argc, char** argv, const std::vector<std::string>& names);
// Pointers into `args` (which must outlive them), null-terminated as argv.
std::vector<char*> ArgvOf(std::vector<std::string>& args);

}  // namespace imca

// The expansions of a settings row (see the top of this file). FILL and
// JSON expect `config` (a pointer for FILL, a reference for JSON) and JSON
// `json` (a JsonObject*) in scope; ROW appends to `rows`.
#define IMCA_SETTING_FLAG(type, name, field, help) ABSL_FLAG(std::optional<type>, name, std::nullopt, help);
#define IMCA_SETTING_FILL(type, name, field, help)                                       \
  if (const std::optional<type> given = absl::GetFlag(FLAGS_##name); given.has_value()) { \
    config->field = *given;                                                              \
  }
#define IMCA_SETTING_JSON(type, name, field, help) ::imca::AddSetting(json, #name, config.field);
#define IMCA_SETTING_ROW(type, name, field, help) rows.push_back(::imca::MakeSettingRow<type>(#name, help));

#endif  // IMCA_BASE_SETTINGS_H_
