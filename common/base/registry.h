#ifndef IMCA_COMMON_BASE_REGISTRY_H_
#define IMCA_COMMON_BASE_REGISTRY_H_

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <initializer_list>
#include <any>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/string_view.h"
#include "common/base/setting_row.h"

namespace imca {

// The T that `options` holds (an entry's own settings, std::any): null if it
// holds none; INVALID_ARGUMENT if it holds another type (another entry's).
template <typename T>
absl::StatusOr<const T*> HeldOptions(const std::any& options) {
  if (!options.has_value()) return nullptr;
  if (const T* held = std::any_cast<T>(&options)) return held;
  return absl::InvalidArgumentError("the options held are another entry's: another algorithm's options or another reward kind's");
}

// Whether an Entry carries its own settings (`std::vector<SettingRow> settings`).
template <typename Entry, typename = void>
struct HasSettings : std::false_type {};
template <typename Entry>
struct HasSettings<Entry, std::void_t<decltype(std::declval<Entry&>().settings)>> : std::true_type {};

// A closed family of named entries (the learner's algorithms, the reward
// server's novelty kinds and credit rules, the scenarios): built once by a
// list of registration calls (BuildRegistry), then read-only (thread-safe to
// read). An Entry has `std::string name` and `bool complete() const` (its
// hooks are set), and may have `std::vector<SettingRow> settings`.
template <typename Entry>
class Registry {
 public:
  // `flag` is the flag that names an entry ("--algo"), for Find's message.
  explicit Registry(std::string flag) : flag_(std::move(flag)) {}

  // Errors: INVALID_ARGUMENT for an empty or taken name or a missing hook.
  // Sets the owner of the entry's setting rows to its name.
  absl::Status Add(Entry entry) {
    if (entry.name.empty()) return absl::InvalidArgumentError(absl::StrCat(flag_, ": an entry needs a name"));
    for (const Entry& e : entries_) {
      if (e.name == entry.name) {
        return absl::InvalidArgumentError(absl::StrCat(flag_, ": '", entry.name, "' is registered twice"));
      }
    }
    if (!entry.complete()) return absl::InvalidArgumentError(absl::StrCat(flag_, ": '", entry.name, "' lacks a hook"));
    if constexpr (HasSettings<Entry>::value) {
      for (SettingRow& row : entry.settings) row.owner = entry.name;
    }
    entries_.push_back(std::move(entry));
    return absl::OkStatus();
  }

  // The entry named `name` ("" names the first registered, the default).
  // Errors: INVALID_ARGUMENT "<flag>: 'x' is not a, b or c".
  absl::StatusOr<const Entry*> Find(absl::string_view name) const {
    if (name.empty() && !entries_.empty()) return &entries_.front();
    for (const Entry& entry : entries_) {
      if (entry.name == name) return &entry;
    }
    std::vector<std::string> names = Names();
    std::string choices = names.empty() ? "none registered" : names.back();
    if (names.size() > 1) {
      names.pop_back();
      choices = absl::StrCat(absl::StrJoin(names, ", "), " or ", choices);
    }
    return absl::InvalidArgumentError(absl::StrCat(flag_, ": '", name, "' is not ", choices));
  }

  std::vector<std::string> Names() const {
    std::vector<std::string> names;
    for (const Entry& entry : entries_) names.push_back(entry.name);
    return names;
  }
  const std::vector<Entry>& entries() const { return entries_; }
  const std::string& flag() const { return flag_; }

  // `rows` (the choosing flag's and the shared settings'), then every
  // entry's settings, a row several entries share (one table) once, its
  // owners joined by ",": what --list prints.
  std::vector<SettingRow> AllSettings(std::vector<SettingRow> rows) const {
    for (const Entry& entry : entries_) {
      for (const SettingRow& row : entry.settings) {
        auto same = std::find_if(rows.begin(), rows.end(), [&](const SettingRow& r) { return r.name == row.name; });
        if (same == rows.end()) {
          rows.push_back(row);
        } else {
          absl::StrAppend(&same->owner, ",", row.owner);
        }
      }
    }
    return rows;
  }

  // The setting rows of every entry but `chosen` (what RefuseOthersSettings
  // refuses when given).
  std::vector<SettingRow> OthersSettings(const Entry* chosen) const {
    std::vector<SettingRow> rows;
    for (const Entry& entry : entries_) {
      if (&entry != chosen) rows.insert(rows.end(), entry.settings.begin(), entry.settings.end());
    }
    return rows;
  }

 private:
  std::string flag_;
  std::vector<Entry> entries_;
};

// The registry R (a Registry<Entry> whose default constructor names its
// flag) of the entries the `registrations` add, in their order: a list's
// lines, one per member, the first the default. A failed registration is a
// programming error: it aborts at the first use, naming the flag and the
// problem.
template <typename R>
R BuildRegistry(std::initializer_list<absl::Status (*)(R*)> registrations) {
  R registry;
  for (absl::Status (*add)(R*) : registrations) {
    const absl::Status added = add(&registry);
    if (!added.ok()) {
      std::fprintf(stderr, "%s registry: %s\n", registry.flag().c_str(), std::string(added.message()).c_str());
      std::abort();
    }
  }
  return registry;
}

}  // namespace imca

#endif  // IMCA_COMMON_BASE_REGISTRY_H_
