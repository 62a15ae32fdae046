#ifndef IMCA_COMMON_BASE_SETTING_ROW_H_
#define IMCA_COMMON_BASE_SETTING_ROW_H_

#include <string>
#include <vector>

namespace imca {

// One setting as --list prints it (settings.h declares settings; a
// registry's entries carry their own rows).
struct SettingRow {
  std::string name;
  std::string type;  // "bool", "int", "float", "string" or "enum".
  std::string help;
  std::vector<std::string> choices;  // An enum's names; empty otherwise.
  // The family member it belongs to (an --algo name, say), or "" for all.
  std::string owner;
};

}  // namespace imca

#endif  // IMCA_COMMON_BASE_SETTING_ROW_H_
