#include "offline/io/io_common.hpp"

#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace sinew::offline::io::detail {

std::string read_whole_file(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) fail(path + ": cannot read: is a directory");
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    const int e = errno;
    fail(path + ": cannot open file" + (e != 0 ? std::string(" (") + std::strerror(e) + ")" : ""));
  }
  std::ostringstream buffer;
  buffer << in.rdbuf();
  if (in.bad()) fail(path + ": read error");
  return buffer.str();
}

std::string to_lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

bool ends_with_ci(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         to_lower(s.substr(s.size() - suffix.size())) == to_lower(suffix);
}

std::string quote_token(std::string_view token) {
  std::string s(token.size() > 40 ? token.substr(0, 40) : token);
  if (token.size() > 40) s += "...";
  for (char& c : s) {
    if (!std::isprint(static_cast<unsigned char>(c))) c = '?';
  }
  return "'" + s + "'";
}

bool parse_double(std::string_view token, double& value) {
  if (token.empty()) return false;
  const char* begin = token.data();
  const char* end = begin + token.size();
  if (*begin == '+') ++begin;  // from_chars rejects a leading '+', which files do contain
  if (begin == end) return false;
  const auto [ptr, ec] = std::from_chars(begin, end, value);
  if (ec == std::errc::result_out_of_range) {
    // Overflow or underflow: strtod gives ±inf or the denormal/zero, like other readers.
    value = std::strtod(std::string(begin, end).c_str(), nullptr);
    return ptr == end;
  }
  return ec == std::errc() && ptr == end;
}

bool parse_integer(std::string_view token, long long& value) {
  if (token.empty()) return false;
  const char* begin = token.data();
  const char* end = begin + token.size();
  if (*begin == '+') ++begin;
  if (begin == end) return false;
  const auto [ptr, ec] = std::from_chars(begin, end, value);
  return ec == std::errc() && ptr == end;
}

std::string number(double v) {
  std::ostringstream s;
  s.precision(6);
  s << v;
  return s.str();
}

std::vector<std::string_view> split_lines(std::string_view text) {
  std::vector<std::string_view> lines;
  std::size_t start = 0;
  while (start < text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string_view::npos) end = text.size();
    std::string_view line = text.substr(start, end - start);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    lines.push_back(line);
    start = end + 1;
  }
  return lines;
}

namespace {
bool is_space(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v';
}
}  // namespace

std::vector<std::string_view> split_whitespace(std::string_view line) {
  std::vector<std::string_view> tokens;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && is_space(line[i])) ++i;
    const std::size_t start = i;
    while (i < line.size() && !is_space(line[i])) ++i;
    if (i > start) tokens.push_back(line.substr(start, i - start));
  }
  return tokens;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (is_space(s.front()) || s.front() == '\n')) s.remove_prefix(1);
  while (!s.empty() && (is_space(s.back()) || s.back() == '\n')) s.remove_suffix(1);
  return s;
}

bool write_file_atomically(const std::string& path, const std::string& contents,
                           std::string* error) {
  const auto failed = [&](const std::string& what) {
    if (error != nullptr) *error = path + ": " + what;
    return false;
  };
  // Unique per process, so concurrent writers of different outputs never share a temporary.
  const std::string tmp = path + ".tmp" + std::to_string(static_cast<long long>(::getpid()));
  std::FILE* f = std::fopen(tmp.c_str(), "wb");
  if (f == nullptr)
    return failed(std::string("cannot open for writing (") + std::strerror(errno) + ")");
  const bool written = std::fwrite(contents.data(), 1, contents.size(), f) == contents.size();
  const int write_errno = errno;
  const bool closed = std::fclose(f) == 0;
  if (!written || !closed) {
    std::remove(tmp.c_str());
    return failed(std::string("write error (") + std::strerror(write_errno) + ")");
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const int e = errno;
    std::remove(tmp.c_str());
    return failed(std::string("cannot move the finished file into place (") + std::strerror(e) +
                  ")");
  }
  return true;
}

void append_double(std::string& out, double v) {
  char buffer[32];
  const int n = std::snprintf(buffer, sizeof buffer, "%.17g", v);
  out.append(buffer, static_cast<std::size_t>(n));
}

}  // namespace sinew::offline::io::detail
