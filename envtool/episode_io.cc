#include "envtool/episode_io.h"

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <iterator>

#include "absl/strings/ascii.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "common/base/atomic_file.h"

namespace imca::envtool {
namespace {

struct LineError {
  int column = 0;  // 1-based; 0: no error.
  std::string message;
};

struct Token {
  absl::string_view text;
  int column;
};

std::vector<Token> Tokenize(absl::string_view line) {
  std::vector<Token> tokens;
  size_t i = 0;
  while (i < line.size()) {
    if (absl::ascii_isspace(static_cast<unsigned char>(line[i]))) {
      ++i;
      continue;
    }
    size_t end = i;
    while (end < line.size() && !absl::ascii_isspace(static_cast<unsigned char>(line[end]))) ++end;
    tokens.push_back({line.substr(i, end - i), static_cast<int>(i) + 1});
    i = end;
  }
  return tokens;
}

// The action a key stands for, or -1.
int KeyAction(char key) {
  const char* found = std::strchr(kActionKeys, absl::ascii_tolower(static_cast<unsigned char>(key)));
  return key != '\0' && found != nullptr ? static_cast<int>(found - kActionKeys) : -1;
}

LineError ParseLine(absl::string_view line, int num_agents, int num_actions, std::vector<int32_t>* out) {
  std::vector<Token> tokens = Tokenize(line);
  if (tokens.size() == 1 && num_agents > 1 && static_cast<int>(tokens[0].text.size()) == num_agents) {
    bool all_keys = true;
    for (char c : tokens[0].text) all_keys &= KeyAction(c) >= 0;
    if (all_keys) {
      const Token compact = tokens[0];
      tokens.clear();
      for (int a = 0; a < num_agents; ++a) tokens.push_back({compact.text.substr(a, 1), compact.column + a});
    }
  }
  const std::string valid =
      absl::StrCat("keys ", absl::string_view(kActionKeys, num_actions), " or numbers 0..", num_actions - 1);
  out->clear();
  for (const Token& token : tokens) {
    if (static_cast<int>(out->size()) == num_agents) {
      return {token.column,
              absl::StrCat("expected ", num_agents, " actions (one per agent), got ", tokens.size())};
    }
    int action = -1;
    if (token.text.size() == 1 && KeyAction(token.text[0]) >= 0) {
      action = KeyAction(token.text[0]);
      if (action >= num_actions) {
        return {token.column, absl::StrCat("'", token.text, "' (stay) is not an action here: ", num_actions,
                                           " actions, ", valid)};
      }
    } else if (absl::SimpleAtoi(token.text, &action) && absl::ascii_isdigit(token.text[0])) {
      if (action >= num_actions) {
        return {token.column, absl::StrCat("action ", token.text, " not in [0, ", num_actions - 1, "]")};
      }
    } else {
      return {token.column, absl::StrCat("'", token.text, "' is not an action (", valid, ")")};
    }
    out->push_back(action);
  }
  if (static_cast<int>(out->size()) < num_agents) {
    return {static_cast<int>(line.size()) + 1,
            absl::StrCat("expected ", num_agents, " actions (one per agent), got ", out->size())};
  }
  return {};
}

std::string CellsJson(const env::GridMap& map, const int32_t* cells, int count) {
  std::vector<std::string> items;
  for (int i = 0; i < count; ++i) {
    items.push_back(absl::StrCat("{\"cell\":", cells[i], ",\"row\":", map.Row(cells[i]),
                                 ",\"col\":", map.Col(cells[i]), "}"));
  }
  return absl::StrCat("[", absl::StrJoin(items, ","), "]");
}

template <typename Pred>
std::string BoolsJson(int count, Pred pred) {
  std::vector<std::string> items;
  for (int i = 0; i < count; ++i) items.push_back(pred(i) ? "true" : "false");
  return absl::StrCat("[", absl::StrJoin(items, ","), "]");
}

}  // namespace

absl::StatusOr<std::vector<int32_t>> ParseActionLine(absl::string_view line, int num_agents,
                                                     int num_actions) {
  std::vector<int32_t> actions;
  const LineError error = ParseLine(line, num_agents, num_actions, &actions);
  if (error.column > 0) {
    return absl::InvalidArgumentError(absl::StrCat("column ", error.column, ": ", error.message));
  }
  return actions;
}

absl::StatusOr<std::vector<std::vector<int32_t>>> ParseActionFile(absl::string_view text,
                                                                  absl::string_view source, int num_agents,
                                                                  int num_actions) {
  std::vector<std::vector<int32_t>> steps;
  int line_number = 0;
  for (absl::string_view line : absl::StrSplit(text, '\n')) {
    ++line_number;
    line = line.substr(0, line.find('#'));
    if (absl::StripAsciiWhitespace(line).empty()) continue;
    std::vector<int32_t> actions;
    const LineError error = ParseLine(line, num_agents, num_actions, &actions);
    if (error.column > 0) {
      return absl::InvalidArgumentError(
          absl::StrCat(source, ":", line_number, ":", error.column, ": ", error.message));
    }
    steps.push_back(std::move(actions));
  }
  return steps;
}

absl::StatusOr<std::vector<std::vector<int32_t>>> ReadActionFile(const std::string& path, int num_agents,
                                                                 int num_actions) {
  std::string text;
  if (path == "-") {
    text.assign(std::istreambuf_iterator<char>(std::cin), std::istreambuf_iterator<char>());
  } else {
    absl::StatusOr<std::string> read = ReadFile(path, "action file");
    if (!read.ok()) return read.status();
    text = *std::move(read);
  }
  return ParseActionFile(text, path == "-" ? "<stdin>" : path, num_agents, num_actions);
}

absl::StatusOr<std::vector<int32_t>> ParseState(absl::string_view text, const env::Scenario& scenario) {
  std::vector<int32_t> state;
  for (absl::string_view item : absl::StrSplit(text, ',')) {
    int32_t value = 0;
    if (!absl::SimpleAtoi(item, &value)) {
      return absl::InvalidArgumentError(absl::StrCat("'", item, "' is not an integer"));
    }
    state.push_back(value);
  }
  if (static_cast<int>(state.size()) != scenario.state_size()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "expected ", scenario.state_size(), " comma-separated integers (z, ", scenario.num_agents(),
        " agent cells, ", scenario.num_npcs(), " entity cells, t), got ", state.size()));
  }
  const absl::Status valid = scenario.ValidateState(state.data());
  if (!valid.ok()) return valid;
  return state;
}

std::string FloatJson(float value) {
  char text[32];
  for (int digits = 6; digits <= 9; ++digits) {
    std::snprintf(text, sizeof(text), "%.*g", digits, value);
    if (std::strtof(text, nullptr) == value) break;
  }
  return text;
}

std::string StateJson(const env::Scenario& scenario, const int32_t* state, absl::Span<const int32_t> actions,
                      absl::Span<const float> rewards, const env::StepOutcome& outcome) {
  const env::GridMap& map = scenario.map();
  const int n = scenario.num_agents();
  auto flag = [](bool b) { return b ? "true" : "false"; };
  return absl::StrCat(
      "{\"t\":", state[scenario.step_index()], ",\"z\":", state[env::kObjectsIndex],
      ",\"agents\":", CellsJson(map, state + 1, n),
      ",\"npcs\":", CellsJson(map, state + 1 + n, scenario.num_npcs()), ",\"actions\":[",
      absl::StrJoin(actions, ","), "],\"rewards\":[",
      absl::StrJoin(rewards, ",", [](std::string* out, float r) { out->append(FloatJson(r)); }),
      "],\"terminated\":", flag(outcome.terminated), ",\"truncated\":", flag(outcome.truncated),
      ",\"success\":", flag(outcome.success),
      ",\"doors_open\":", BoolsJson(map.num_doors(), [&](int d) { return scenario.DoorOpen(state, d); }),
      ",\"treasures_collected\":",
      BoolsJson(static_cast<int>(map.treasures().size()),
                [&](int k) { return scenario.TreasureCollected(state, k); }),
      ",\"buttons_pressed\":",
      BoolsJson(static_cast<int>(map.buttons().size()),
                [&](int k) { return scenario.ButtonPressed(state, k); }),
      "}");
}

std::string JsonString(absl::string_view text) {
  std::string out = "\"";
  for (char c : text) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char escaped[8];
          std::snprintf(escaped, sizeof(escaped), "\\u%04x", c);
          out += escaped;
        } else {
          out += c;
        }
    }
  }
  return out + "\"";
}

}  // namespace imca::envtool
