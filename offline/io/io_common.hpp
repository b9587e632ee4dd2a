#pragma once
/// Internal helpers shared by the offline/io readers and writers (not part of the public API):
/// whole-file reading, locale-independent number parsing, message formatting, atomic writes.

#include <cstddef>
#include <cstdint>
#include <exception>
#include <new>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace sinew::offline::io::detail {

/// Internal failure carrying the final one-line message; caught at the public entry points.
struct ReadError {
  std::string message;
};

[[noreturn]] inline void fail(std::string message) {
  throw ReadError{std::move(message)};
}
[[noreturn]] inline void fail_line(const std::string& file, long long line,
                                   const std::string& what) {
  throw ReadError{file + ":" + std::to_string(line) + ": " + what};
}

/// Runs a reader body and turns whatever it throws into Result::error, one line naming path:
/// the single place where the public read_* entry points catch.
template <class Result, class Body>
Result guarded_read(const std::string& path, const Body& body) {
  Result failed;
  try {
    return body();
  } catch (const ReadError& e) {
    failed.error = e.message;
  } catch (const std::bad_alloc&) {
    failed.error = path + ": out of memory while reading";
  } catch (const std::exception& e) {
    failed.error = path + ": " + e.what();
  } catch (...) {
    failed.error = path + ": unknown error while reading";
  }
  return failed;
}

/// The whole file as bytes. Throws ReadError "file: cannot open file (reason)".
std::string read_whole_file(const std::string& path);

std::string to_lower(std::string s);
bool ends_with_ci(const std::string& s, const std::string& suffix);

/// A token shortened and made printable for quoting in a message: 'abc'.
std::string quote_token(std::string_view token);

/// Parses the whole token as a double (locale-independent; accepts "nan", "inf"; overflow gives
/// ±inf, which callers reject as non-finite). False if the token is not entirely a number.
bool parse_double(std::string_view token, double& value);
/// Parses the whole token as a base-10 integer. False if not an integer or out of range.
bool parse_integer(std::string_view token, long long& value);

/// A number for a message (6 significant digits).
std::string number(double v);

/// Splits text into lines (without '\n' or a trailing '\r').
std::vector<std::string_view> split_lines(std::string_view text);
/// Whitespace-separated tokens of a line.
std::vector<std::string_view> split_whitespace(std::string_view line);
std::string_view trim(std::string_view s);

/// Writes `contents` to `path` atomically (temporary file in the same folder + rename). Returns
/// false and sets *error to one line on failure.
bool write_file_atomically(const std::string& path, const std::string& contents,
                           std::string* error);

/// Appends %.17g of v (round-trips every double exactly).
void append_double(std::string& out, double v);

}  // namespace sinew::offline::io::detail
