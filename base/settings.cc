#include "base/settings.h"

#include <algorithm>

#include "absl/strings/match.h"
#include "absl/strings/strip.h"
#include "absl/strings/str_cat.h"

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

std::vector<char*> ArgvOf(std::vector<std::string>& args) {
  std::vector<char*> out;
  for (std::string& arg : args) out.push_back(arg.data());
  out.push_back(nullptr);
  return out;
}

}  // namespace imca
