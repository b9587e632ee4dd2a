#pragma once
/// The one-line messages of an unreadable JSON file, shared by every JSON reader (the case and
/// marker readers of offline/io, the tools' init, beam and checkpoint files):
/// "path:line:column: invalid JSON: what". Text only: the readers pass the parser's own
/// message and byte offset, so this header needs no JSON library.

#include <algorithm>
#include <cctype>
#include <cstddef>
#include <string>
#include <string_view>

namespace sinew::common::detail {

/// "line:column" (both from 1) of a byte offset in text.
inline std::string line_column(std::string_view text, std::size_t offset) {
  std::size_t line = 1, column = 1;
  for (std::size_t i = 0; i < std::min(offset, text.size()); ++i) {
    if (text[i] == '\n') {
      ++line;
      column = 1;
    } else {
      ++column;
    }
  }
  return std::to_string(line) + ":" + std::to_string(column);
}

/// A syntax error: what is the parser's message (nlohmann's "[json.exception.parse_error.101]
/// parse error at line L, column C: ..." loses its prefix), byte the parser's 1-based offset.
inline std::string json_syntax_error(const std::string& path, std::string_view text,
                                     std::string what, std::size_t byte) {
  const auto column_at = what.find("column ");
  const auto colon = what.find(": ", column_at == std::string::npos ? 0 : column_at);
  if (colon != std::string::npos) what = what.substr(colon + 2);
  return path + ":" + line_column(text, byte > 0 ? byte - 1 : 0) + ": invalid JSON: " + what;
}

/// Any other parser error, which reports no position (e.g. "number overflow parsing '1e400'"):
/// the quoted token's first occurrence as a whole number in the text gives it.
inline std::string json_value_error(const std::string& path, std::string_view text,
                                    std::string what) {
  const auto bracket = what.find("] ");
  if (bracket != std::string::npos) what = what.substr(bracket + 2);
  const auto open = what.find('\''), close = what.rfind('\'');
  if (open != std::string::npos && close > open + 1) {
    const std::string token = what.substr(open + 1, close - open - 1);
    const auto part_of_number = [](char c) {
      return std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '-' || c == '+';
    };
    for (auto at = text.find(token); at != std::string_view::npos; at = text.find(token, at + 1)) {
      const std::size_t after = at + token.size();
      if ((at == 0 || !part_of_number(text[at - 1])) &&
          (after >= text.size() || !part_of_number(text[after]))) {
        return path + ":" + line_column(text, at) + ": invalid JSON: " + what +
               " (not a finite double)";
      }
    }
  }
  return path + ": invalid JSON: " + what;
}

}  // namespace sinew::common::detail
