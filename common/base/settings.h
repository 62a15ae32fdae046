#ifndef IMCA_COMMON_BASE_SETTINGS_H_
#define IMCA_COMMON_BASE_SETTINGS_H_

// A configuration's settings, each declared once. Beside a config struct, a
// table of rows as an X-macro:
//
//   #define IMCA_FOO_SETTINGS(X) (a backslash ends each line but the last)
//     X(int, epochs, epochs, "PPO epochs per iteration")
//     X(double, lr, ppo.learning_rate, "Adam learning rate")
//
// A row is (type, name, field, help): the value's type, the name of its flag
// and of its key in --print_config and --list, the field it sets (a member
// path inside the config), and one line of help. One `*_flags.cc` (or an
// entry's `*_registration.cc`) expands the table twice:
//   IMCA_FOO_SETTINGS(IMCA_SETTING_FLAG)  the flags, std::optional<type> (a
//       setting not given keeps the config's default, which may be the
//       scenario's or the algorithm's), at global scope;
//   IMCA_SETTING_TABLE(FooSettings, Foo, IMCA_FOO_SETTINGS)  a function
//       returning the table as a SettingTable<Foo>: its --list rows, the
//       flags given set over a Foo, a Foo as "flag": value (--print_config;
//       passed back as flags, it resolves to the same config).
// An enum type is a setting type when its namespace declares, for ADL,
// AbslParseFlag / AbslUnparseFlag (its flag spelling) and
// `std::vector<std::string> SettingChoices(E)` (every name, in order).
// Booleans take the bare form (--x, --nox) as well as --x=true|false:
// ParseCommandLineWithSettings.

#include <cstdint>
#include <optional>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "common/base/json.h"
#include "common/base/setting_row.h"

namespace imca {

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

// One row of a table, expanded for config type C (IMCA_SETTING_TABLE).
template <typename C>
struct Setting {
  SettingRow row;
  void (*fill)(C* config);  // Sets the field if the flag was given.
  void (*json)(const C& config, JsonObject* json);
};

// A config's settings as one object. Immutable; thread-safe.
template <typename C>
class SettingTable {
 public:
  explicit SettingTable(std::vector<Setting<C>> settings) : settings_(std::move(settings)) {}
  std::vector<SettingRow> Rows() const {
    std::vector<SettingRow> rows;
    for (const Setting<C>& s : settings_) rows.push_back(s.row);
    return rows;
  }
  // The flags given, over `config`.
  void Fill(C* config) const {
    for (const Setting<C>& s : settings_) s.fill(config);
  }
  void Json(const C& config, JsonObject* json) const {
    for (const Setting<C>& s : settings_) s.json(config, json);
  }

 private:
  std::vector<Setting<C>> settings_;
};

// `rows` as a JSON array of {"name", "type", "help", "choices", "owner"}.
std::string SettingRowsJson(const std::vector<SettingRow>& rows);

// The settings of `rows` given on the command line (a flag of
// IMCA_SETTING_FLAG holds a value), by name. Needs the flags linked in (the
// caller's *_flags.cc); a row without a flag is not given.
std::vector<std::string> GivenSettings(const std::vector<SettingRow>& rows);

// Errors: INVALID_ARGUMENT "--x is <owner>'s setting; <choice_flag> is <chosen>"
// for the first row of `others` given that `own` lacks (a setting of another
// algorithm or reward kind, which would be ignored).
absl::Status RefuseOthersSettings(const std::vector<SettingRow>& own, const std::vector<SettingRow>& others,
                                  absl::string_view choice_flag, absl::string_view chosen);

// argv with every bare boolean flag of `names` spelled out for absl, which
// reads an optional<bool> flag's value from the next argument: --x and -x
// become --x=true, --nox and -nox --x=false; the rest, and everything after
// "--", is as given.
std::vector<std::string> BareBooleanFlags(int argc, char** argv, const std::vector<std::string>& names);
// Pointers into `args` (which must outlive them), null-terminated as argv.
std::vector<char*> ArgvOf(std::vector<std::string>& args);
// absl::ParseCommandLine of argv with the boolean settings of `rows` taking
// the bare form (BareBooleanFlags).
void ParseCommandLineWithSettings(int argc, char** argv, const std::vector<SettingRow>& rows);

}  // namespace imca

// The expansions of a settings row (see the top of this file).
#define IMCA_SETTING_FLAG(type, name, field, help) ABSL_FLAG(std::optional<type>, name, std::nullopt, help);
#define IMCA_SETTING_OF(type, name, field, help)                                                         \
  ::imca::Setting<SettingConfig>{                                                                        \
      ::imca::MakeSettingRow<type>(#name, help),                                                         \
      [](SettingConfig* config) {                                                                        \
        if (const std::optional<type> given = absl::GetFlag(FLAGS_##name); given.has_value()) {          \
          config->field = *given;                                                                        \
        }                                                                                                \
      },                                                                                                 \
      [](const SettingConfig& config, ::imca::JsonObject* json) { ::imca::AddSetting(json, #name, config.field); }},
#define IMCA_SETTING_TABLE(Function, Config, TABLE)                                                    \
  const ::imca::SettingTable<Config>& Function() {                                                      \
    using SettingConfig = Config;                                                                       \
    static const ::imca::SettingTable<Config>* const kTable = new ::imca::SettingTable<Config>({TABLE(IMCA_SETTING_OF)}); \
    return *kTable;                                                                                     \
  }

#endif  // IMCA_COMMON_BASE_SETTINGS_H_
