#include "common/base/settings.h"

#include <algorithm>

#include "absl/flags/parse.h"
#include "absl/flags/reflection.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/strip.h"

namespace imca {

std::string SettingRowsJson(const std::vector<SettingRow>& rows) {
  std::string out = "[";
  for (size_t i = 0; i < rows.size(); ++i) {
    const SettingRow& r = rows[i];
    absl::StrAppend(&out, i > 0 ? ", " : "",
                    JsonObject()
                        .Add("name", r.name)
                        .Add("type", r.type)
                        .Add("help", r.help)
                        .Add("choices", r.choices)
                        .Add("owner", r.owner)
                        .Text());
  }
  return out + "]";
}

std::vector<std::string> GivenSettings(const std::vector<SettingRow>& rows) {
  std::vector<std::string> given;
  for (const SettingRow& row : rows) {
    const absl::CommandLineFlag* flag = absl::FindCommandLineFlag(row.name);
    // An optional flag not given unparses as "".
    if (flag != nullptr && !flag->CurrentValue().empty()) given.push_back(row.name);
  }
  return given;
}

absl::Status RefuseOthersSettings(const std::vector<SettingRow>& own, const std::vector<SettingRow>& others,
                                  absl::string_view choice_flag, absl::string_view chosen) {
  for (const SettingRow& row : others) {
    const bool owned = std::any_of(own.begin(), own.end(), [&](const SettingRow& r) { return r.name == row.name; });
    if (owned || GivenSettings({row}).empty()) continue;
    return absl::InvalidArgumentError(absl::StrCat("--", row.name, " is ", row.owner, "'s setting; ", choice_flag,
                                                   " is ", chosen));
  }
  return absl::OkStatus();
}

std::vector<std::string> BareBooleanFlags(int argc, char** argv, const std::vector<std::string>& names) {
  std::vector<std::string> out;
  const auto known = [&](absl::string_view name) {
    return std::find(names.begin(), names.end(), name) != names.end();
  };
  bool flags_ended = false;
  for (int i = 0; i < argc; ++i) {
    const absl::string_view arg = argv[i];
    if (i == 0 || flags_ended) {
      out.emplace_back(arg);
      continue;
    }
    if (arg == "--") flags_ended = true;
    absl::string_view name = arg;
    if (!absl::ConsumePrefix(&name, "--")) absl::ConsumePrefix(&name, "-");
    if (name.size() == arg.size() || absl::StrContains(name, '=')) {
      out.emplace_back(arg);  // Not a flag, or a flag with its value.
    } else if (known(name)) {
      out.push_back(absl::StrCat("--", name, "=true"));
    } else if (absl::ConsumePrefix(&name, "no") && known(name)) {
      out.push_back(absl::StrCat("--", name, "=false"));
    } else {
      out.emplace_back(arg);
    }
  }
  return out;
}

void ParseCommandLineWithSettings(int argc, char** argv, const std::vector<SettingRow>& rows) {
  std::vector<std::string> bools;
  for (const SettingRow& row : rows) {
    if (row.type == "bool") bools.push_back(row.name);
  }
  std::vector<std::string> args = BareBooleanFlags(argc, argv, bools);
  std::vector<char*> args_argv = ArgvOf(args);
  absl::ParseCommandLine(static_cast<int>(args.size()), args_argv.data());
}

std::vector<char*> ArgvOf(std::vector<std::string>& args) {
  std::vector<char*> out;
  for (std::string& arg : args) out.push_back(arg.data());
  out.push_back(nullptr);
  return out;
}

}  // namespace imca
