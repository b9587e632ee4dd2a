#pragma once
/// Reading JSON files for the command-line tools, with errors a user can act on: every failure is a
/// single line naming the file, the line and column, and for a value its JSON path
/// ("beam.json:4:17: nodes[3][1] must be a finite number"). A document that came from no file (a
/// Python dict) has no lines: its messages name the path alone ("<dict>: nodes[3][1] ...").

#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/detail/json_error.hpp"

namespace sinew::tools {

/// An input error; what() is the complete one-line message.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A value the parser accepted but the reader cannot use: what() is "<file>: <path> <what>";
/// located(text) puts the value's line and column in, given the document's text.
class JsonValueError : public InputError {
 public:
  JsonValueError(std::string file, std::vector<common::detail::JsonPathStep> steps,
                 std::string message)
      : InputError(file + ": " + message),
        file_(std::move(file)),
        steps_(std::move(steps)),
        message_(std::move(message)) {}
  std::string located(std::string_view text) const;
  /// The same error with `more` added to its message.
  JsonValueError appended(const std::string& more) const {
    return JsonValueError(file_, steps_, message_ + more);
  }

 private:
  std::string file_;
  std::vector<common::detail::JsonPathStep> steps_;
  std::string message_;
};

/// Parses a JSON file. Throws InputError "<path>: cannot open ..." or "<path>:<line>:<col>: ...".
nlohmann::json read_json_file(const std::string& path);
/// The same, with the file's text kept.
struct JsonFile {
  nlohmann::json root;
  std::string text;
};
JsonFile read_json_text(const std::string& path);

/// Reads a JSON file and runs parse(root) on it; a JsonValueError parse throws comes out as an
/// InputError with the value's line and column.
template <class Parse>
auto parse_json_file(const std::string& path, Parse parse) {
  const JsonFile file = read_json_text(path);
  try {
    return parse(file.root);
  } catch (const JsonValueError& e) {
    throw InputError(e.located(file.text));
  }
}

/// Writes JSON atomically (temporary file + rename), so a crash never leaves half a result.
void write_json_file(const std::string& path, const nlohmann::json& value, int indent = 1);

/// Typed access into a JSON document that remembers where it is, for messages like
/// "beam.json: material.E must be a number".
class JsonCursor {
 public:
  /// The root of a document read from `file` (its name in messages).
  JsonCursor(const nlohmann::json& value, std::string file)
      : value_(&value), file_(std::move(file)) {}

  const nlohmann::json& value() const { return *value_; }
  const std::string& path() const { return path_; }
  const std::string& file() const { return file_; }
  bool has(const std::string& key) const;
  /// Member `key` of an object; throws when missing (required) or when this is not an object.
  JsonCursor at(const std::string& key) const;
  /// Element i of an array.
  JsonCursor at(std::size_t i) const;
  std::size_t array_size() const;  ///< throws unless an array
  double finite_number() const;    ///< throws unless a finite number
  double positive_number() const;  ///< throws unless finite and > 0
  long integer() const;            ///< throws unless an integer
  bool boolean() const;
  std::string string() const;
  /// Throws when the object has a key outside `allowed` (catches typos such as "lods").
  void expect_keys(const std::vector<std::string>& allowed) const;

  /// Throws JsonValueError "<file>: <path> <what>".
  [[noreturn]] void fail(const std::string& what) const;

 private:
  JsonCursor(const JsonCursor& parent, const nlohmann::json& value,
             common::detail::JsonPathStep step);

  const nlohmann::json* value_;
  std::string file_;
  std::string path_;  // "material.E", "nodes[3][1]"; empty at the root
  std::vector<common::detail::JsonPathStep> steps_;
};

}  // namespace sinew::tools
