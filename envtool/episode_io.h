#ifndef IMCA_ENVTOOL_EPISODE_IO_H_
#define IMCA_ENVTOOL_EPISODE_IO_H_

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/types/span.h"
#include "common/env/env.h"

// Text formats of the imca_env tool (docs/envtool.md): action lines and
// files, the --state flag, and the JSON line printed per step. Free functions
// without state; thread-safe.
namespace imca::envtool {

// Key of each action, indexed by env::Action: w up, s down, a left, d right,
// x stay.
inline constexpr char kActionKeys[] = "wsadx";

// Parses one step: num_agents whitespace-separated tokens, each a key from
// kActionKeys or an action number in [0, num_actions). One token made of
// exactly num_agents keys is also accepted ("wd" is "w d"). 'x' is rejected
// when num_actions is 4. Errors: INVALID_ARGUMENT "column C: ..." (1-based).
absl::StatusOr<std::vector<int32_t>> ParseActionLine(absl::string_view line, int num_agents, int num_actions);

// Parses an action file: one step per line as ParseActionLine; '#' starts a
// comment; blank lines are skipped. Errors: INVALID_ARGUMENT
// "source:line:column: ...".
absl::StatusOr<std::vector<std::vector<int32_t>>> ParseActionFile(absl::string_view text,
                                                                  absl::string_view source, int num_agents,
                                                                  int num_actions);

// Reads `path` ("-": standard input) and parses it as above. Errors:
// NOT_FOUND naming the path if it cannot be read, plus those of ParseActionFile.
absl::StatusOr<std::vector<std::vector<int32_t>>> ReadActionFile(const std::string& path, int num_agents,
                                                                 int num_actions);

// Parses "z,c1,...,t": scenario.state_size() comma-separated integers that
// must pass scenario.ValidateState. Errors: INVALID_ARGUMENT saying which.
absl::StatusOr<std::vector<int32_t>> ParseState(absl::string_view text, const env::Scenario& scenario);

// One JSON object (no newline) for `state`: t, z, agent and npc cells with
// row and col, the step's actions and rewards (empty for the initial state),
// the outcome flags, and per door / treasure / button whether it is open /
// collected / pressed.
std::string StateJson(const env::Scenario& scenario, const int32_t* state, absl::Span<const int32_t> actions,
                      absl::Span<const float> rewards, const env::StepOutcome& outcome);

// The shortest decimal (6 to 9 significant digits) that reads back as
// `value`, so JSON consumers get the float bit for bit.
std::string FloatJson(float value);

// `text` as a JSON string literal, quotes included.
std::string JsonString(absl::string_view text);

}  // namespace imca::envtool

#endif  // IMCA_ENVTOOL_EPISODE_IO_H_
