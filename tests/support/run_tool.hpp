#pragma once
/// Runs a command-line tool of the build for end-to-end tests: exit status, stdout and stderr.
#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace sinew::testing {

struct ToolResult {
  int exit_status = -1;  ///< the process's exit code; -1 if it did not exit normally (crash)
  std::string out, err;
};

inline std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

inline void write_text(const std::filesystem::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

/// Runs `command` (a shell command line) with stdout and stderr captured to files in `dir`.
inline ToolResult run_tool(const std::string& command, const std::filesystem::path& dir) {
  const auto out = dir / "stdout.txt", err = dir / "stderr.txt";
  const std::string line = command + " >" + out.string() + " 2>" + err.string();
  const int raw = std::system(line.c_str());
  ToolResult r;
  if (raw != -1 && WIFEXITED(raw)) r.exit_status = WEXITSTATUS(raw);
  r.out = read_text(out);
  r.err = read_text(err);
  return r;
}

/// A fresh empty folder under the build tree for one test.
inline std::filesystem::path scratch_dir(const std::string& name) {
  const auto dir = std::filesystem::path(SINEW_BINARY_DIR) / "test_scratch" / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace sinew::testing
