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
#include <vector>

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

/// One step of a path into a JSON document: an object key or an array index.
struct JsonPathStep {
  bool is_key = false;
  std::string key;
  std::size_t index = 0;
};

/// Finds the byte offset of the value at a JSON path by scanning the text of a document that has
/// already been parsed (so it is valid): for "file:line:column: path: what" about a value.
class JsonLocator {
 public:
  explicit JsonLocator(std::string_view text) : t_(text) {}

  std::size_t find(const std::vector<JsonPathStep>& path) const {
    std::size_t p = skip_ws(0);
    for (const auto& step : path) {
      if (p >= t_.size()) return p;
      if (step.is_key && t_[p] == '{') {
        p = skip_ws(p + 1);
        while (p < t_.size() && t_[p] == '"') {
          const std::size_t key_end = skip_string(p);
          const bool match = decode_key(t_.substr(p, key_end - p)) == step.key;
          p = skip_ws(skip_ws(key_end) + 1);  // after ':'
          if (match) break;
          p = skip_ws(skip_value(p));
          if (p < t_.size() && t_[p] == ',') p = skip_ws(p + 1);
        }
      } else if (!step.is_key && t_[p] == '[') {
        p = skip_ws(p + 1);
        for (std::size_t i = 0; i < step.index && p < t_.size(); ++i) {
          p = skip_ws(skip_value(p));
          if (p < t_.size() && t_[p] == ',') p = skip_ws(p + 1);
        }
      } else {
        return p;
      }
    }
    return p;
  }

 private:
  // A key's text between its quotes with the common escapes decoded (\uXXXX is left as written:
  // such a key is not matched, and the position falls back to its object).
  static std::string decode_key(std::string_view raw) {
    std::string key;
    for (std::size_t i = 1; i + 1 < raw.size(); ++i) {
      char c = raw[i];
      if (c == '\\' && i + 2 < raw.size()) {
        const char e = raw[++i];
        c = e == 'n'   ? '\n'
            : e == 't' ? '\t'
            : e == 'r' ? '\r'
            : e == 'b' ? '\b'
            : e == 'f' ? '\f'
                       : e;
        if (e == 'u') key += '\\';
      }
      key += c;
    }
    return key;
  }
  std::size_t skip_ws(std::size_t p) const {
    while (p < t_.size() && (t_[p] == ' ' || t_[p] == '\t' || t_[p] == '\n' || t_[p] == '\r')) ++p;
    return p;
  }
  std::size_t skip_string(std::size_t p) const {  // p at the opening quote
    for (++p; p < t_.size(); ++p) {
      if (t_[p] == '\\')
        ++p;
      else if (t_[p] == '"')
        return p + 1;
    }
    return p;
  }
  std::size_t skip_value(std::size_t p) const {
    if (p >= t_.size()) return p;
    if (t_[p] == '"') return skip_string(p);
    if (t_[p] == '{' || t_[p] == '[') {
      int depth = 0;
      for (; p < t_.size(); ++p) {
        if (t_[p] == '"') {
          p = skip_string(p) - 1;
        } else if (t_[p] == '{' || t_[p] == '[') {
          ++depth;
        } else if (t_[p] == '}' || t_[p] == ']') {
          if (--depth == 0) return p + 1;
        }
      }
      return p;
    }
    while (p < t_.size() && t_[p] != ',' && t_[p] != ']' && t_[p] != '}' && t_[p] != ' ' &&
           t_[p] != '\n' && t_[p] != '\r' && t_[p] != '\t')
      ++p;
    return p;
  }

  std::string_view t_;
};

}  // namespace sinew::common::detail
