#pragma once
/// Reading JSON files for the command-line tools, with errors a user can act on: every failure is a
/// single line naming the file, and the line and column (parse errors) or the JSON path of the
/// offending value ("beam.json: nodes[3][1] must be a finite number").

#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <vector>

namespace sinew::tools {

/// An input error; what() is the complete one-line message.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Parses a JSON file. Throws InputError "<path>: cannot open ..." or "<path>:<line>:<col>: ...".
nlohmann::json read_json_file(const std::string& path);

/// Writes JSON atomically (temporary file + rename), so a crash never leaves half a result.
void write_json_file(const std::string& path, const nlohmann::json& value, int indent = 1);

/// Typed access into a JSON document that remembers where it is, for messages like
/// "beam.json: material.E must be a number".
class JsonCursor {
 public:
  JsonCursor(const nlohmann::json& value, std::string file, std::string path = "")
      : value_(&value), file_(std::move(file)), path_(std::move(path)) {}

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

  [[noreturn]] void fail(const std::string& what) const;

 private:
  const nlohmann::json* value_;
  std::string file_;
  std::string path_;
};

}  // namespace sinew::tools
