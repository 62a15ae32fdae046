#ifndef IMCA_REWARD_SERVER_NOVELTY_REGISTRY_H_
#define IMCA_REWARD_SERVER_NOVELTY_REGISTRY_H_

#include <any>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "common/base/json.h"
#include "common/base/registry.h"
#include "common/base/settings.h"
#include "common/env/env.h"
#include "common/nn/threads.h"
#include "reward_server/credit.h"
#include "reward_server/novelty/novelty.h"

namespace imca::reward {

// The reward server's novelty kinds, each registered beside its code
// (count_registration.cc, ...) by one line of novelties.def, the one place
// that names them all. An entry carries everything the server, its
// binary and the tools know of a kind.
struct NoveltyEntry {
  std::string name;  // --reward.
  std::string help;  // One line: what it is.
  // Its differences from ScorerConfig's defaults (credit, beta), before the
  // scenario's bonus scale.
  std::function<void(ScorerConfig* config)> defaults;
  // Its own settings (common/base/settings.h), held in a std::any of its options
  // type (none: that type's defaults): the rows --list prints, the flags
  // given set over `options`, and "flag": value (--print_config). Kinds may
  // share one options type and table (eiti and edti do).
  std::vector<SettingRow> settings;
  std::function<void(std::any* options)> fill_from_flags;
  std::function<void(const std::any& options, JsonObject* json)> add_json;
  // The kind's novelty on `scenario`. Errors: INVALID_ARGUMENT for settings
  // it refuses (options of another kind among them).
  std::function<absl::StatusOr<std::unique_ptr<Novelty>>(const env::Scenario& scenario, const ScorerConfig& config,
                                                          const std::any& options)>
      create;

  bool complete() const { return defaults && fill_from_flags && add_json && create; }
};

// The reward server's registry (common/base/registry.h): Find's errors name
// --reward.
class NoveltyRegistry : public Registry<NoveltyEntry> {
 public:
  NoveltyRegistry() : Registry("--reward") {}
};

// Every novelty kind (novelties.def; the first is the default), built on
// first use.
const NoveltyRegistry& Novelties();

// The options of type T in `options`: T's defaults if it holds none;
// INVALID_ARGUMENT if it holds another type (another kind's options).
template <typename T>
absl::StatusOr<T> KindOptions(const std::any& options) {
  absl::StatusOr<const T*> held = HeldOptions<T>(options);
  if (!held.ok()) return held.status();
  return *held != nullptr ? **held : T();
}

// The novelty of a kind whose options are an Options.
template <typename Options>
using NoveltyFactory = absl::StatusOr<std::unique_ptr<Novelty>> (*)(const env::Scenario& scenario,
                                                                     const ScorerConfig& config,
                                                                     const Options& options);

// The entry of a kind whose own settings are an Options declared by `table`
// (none: `table` null), made by `create`.
template <typename Options>
NoveltyEntry MakeNoveltyEntry(std::string name, std::string help, const SettingTable<Options>* table,
                              void (*defaults)(ScorerConfig* config), NoveltyFactory<Options> create) {
  return {
      .name = std::move(name),
      .help = std::move(help),
      .defaults = defaults,
      .settings = table != nullptr ? table->Rows() : std::vector<SettingRow>(),
      .fill_from_flags =
          [table](std::any* options) {
            if (table == nullptr) return;
            Options filled = KindOptions<Options>(*options).value_or(Options());
            table->Fill(&filled);
            *options = filled;
          },
      .add_json =
          [table](const std::any& options, JsonObject* json) {
            if (table != nullptr) table->Json(KindOptions<Options>(options).value_or(Options()), json);
          },
      .create = [create](const env::Scenario& scenario, const ScorerConfig& config,
                         const std::any& options) -> absl::StatusOr<std::unique_ptr<Novelty>> {
        absl::StatusOr<Options> held = KindOptions<Options>(options);
        if (!held.ok()) return held.status();
        return create(scenario, config, *held);
      },
  };
}

// The factory of a learned kind T (T::Create(scenario, config, options)):
// LibTorch's threads set first (once per process).
template <typename T, typename Options>
absl::StatusOr<std::unique_ptr<Novelty>> CreateLearned(const env::Scenario& scenario, const ScorerConfig& config,
                                                      const Options& options) {
  nn::SetTorchThreads(config.threads);
  absl::StatusOr<std::unique_ptr<T>> made = T::Create(scenario, config, options);
  if (!made.ok()) return made.status();
  return std::unique_ptr<Novelty>(*std::move(made));
}

// The global bonuses' defaults (count, rnd, sf): half the novelty, split by
// IMCA (the scale of every row of docs/results.md).
inline void GlobalBonusDefaults(ScorerConfig* config) {
  config->credit = "imca";
  config->beta = 0.5;
}

// Registrations, one per file beside each kind's code and one per line of
// novelties.def.
#define IMCA_NOVELTY(Prefix) absl::Status Register##Prefix(NoveltyRegistry* registry);
#include "reward_server/novelty/novelties.def"
#undef IMCA_NOVELTY

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_NOVELTY_REGISTRY_H_
