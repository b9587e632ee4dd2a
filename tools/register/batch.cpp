#include "tools/register/batch.hpp"

#include <fmt/core.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <iostream>
#include <map>

#include "tools/io/json_file.hpp"

namespace sinew::tools {
namespace {

namespace fs = std::filesystem;

std::string resolve(const std::string& manifest_path, const JsonCursor& field) {
  const std::string name = field.string();
  if (name.empty()) field.fail("must name a file or folder (it is empty)");
  const fs::path p(name);
  if (p.is_absolute()) return p.lexically_normal().string();
  return (fs::path(manifest_path).parent_path() / p).lexically_normal().string();
}

struct CaseOutcome {
  int exit_status = 1;        ///< the child's exit status (1 when it died of a signal)
  std::optional<int> signal;  ///< the signal that ended the child
  std::string error;          ///< set when the child could not be started
  double seconds = 0.0;
};

std::string describe(const CaseOutcome& o) {
  if (!o.error.empty()) return "not run (" + o.error + ")";
  if (o.signal) return fmt::format("crashed (signal {}: {})", *o.signal, strsignal(*o.signal));
  switch (o.exit_status) {
    case 0:
      return "registered";
    case 1:
      return "registration failed (exit 1, see its report.json)";
    case 2:
      return "bad input (exit 2)";
    default:
      return fmt::format("failed (exit {})", o.exit_status);
  }
}

// The case in a child process: a crash, an abort in a library or a leak stays there.
CaseOutcome run_isolated(const BatchCase& c, const BatchCaseRunner& run_case) {
  CaseOutcome outcome;
  const auto start = std::chrono::steady_clock::now();
  std::fflush(nullptr);  // nothing buffered may be printed twice
  std::cout.flush();
  const pid_t pid = fork();
  if (pid < 0) {
    outcome.error = std::string("fork failed: ") + std::strerror(errno);
    return outcome;
  }
  if (pid == 0) {
    int status = 1;
    try {
      status = run_case(c);
    } catch (const std::exception& e) {
      std::cerr << "sinew-register: " << e.what() << "\n";
      status = 2;
    } catch (...) {
      std::cerr << "sinew-register: unknown error\n";
      status = 2;
    }
    std::cout.flush();
    std::cerr.flush();
    std::fflush(nullptr);
    _exit(status);  // no atexit handlers or static destructors of the parent's copy
  }
  int raw = 0;
  while (waitpid(pid, &raw, 0) < 0) {
    if (errno != EINTR) {
      outcome.error = std::string("waitpid failed: ") + std::strerror(errno);
      return outcome;
    }
  }
  if (WIFEXITED(raw)) {
    outcome.exit_status = WEXITSTATUS(raw);
  } else if (WIFSIGNALED(raw)) {
    outcome.signal = WTERMSIG(raw);
  }
  outcome.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return outcome;
}

}  // namespace

BatchManifest read_batch_manifest(const std::string& path) {
  return parse_json_file(
      path, [&](const nlohmann::json& doc) { return parse_batch_manifest(doc, path); });
}

BatchManifest parse_batch_manifest(const nlohmann::json& doc, const std::string& path) {
  const JsonCursor root(doc, path);
  root.expect_keys({"cases"});
  const JsonCursor cases = root.at("cases");
  const std::size_t n = cases.array_size();
  if (n == 0) cases.fail("is empty");
  BatchManifest m;
  m.path = path;
  std::map<std::string, std::size_t> out_dirs;  // normalised folder → first case using it
  for (std::size_t i = 0; i < n; ++i) {
    const JsonCursor e = cases.at(i);
    if (!e.value().is_object()) e.fail("must be {\"case\": FILE, \"out\": FOLDER}");
    e.expect_keys({"case", "out", "truth"});
    BatchCase c;
    c.case_path = resolve(path, e.at("case"));
    c.out_dir = resolve(path, e.at("out"));
    if (e.has("truth")) c.truth_path = resolve(path, e.at("truth"));
    const std::string key = fs::weakly_canonical(fs::absolute(c.out_dir)).string();
    const auto [it, inserted] = out_dirs.emplace(key, i);
    if (!inserted) {
      e.at("out").fail("= \"" + e.at("out").string() + "\" is also the output folder of cases[" +
                       std::to_string(it->second) + "]");
    }
    m.cases.push_back(std::move(c));
  }
  return m;
}

std::optional<std::size_t> select_batch_task(const BatchManifest& manifest,
                                             std::optional<long> task, const char* slurm_task) {
  long index = 0;
  std::string from;
  if (task) {
    index = *task;
    from = "--task " + std::to_string(*task);
  } else if (slurm_task != nullptr) {
    const std::string text = slurm_task;
    char* end = nullptr;
    errno = 0;
    index = std::strtol(text.c_str(), &end, 10);
    if (text.empty() || *end != '\0' || errno == ERANGE || index < 0) {
      throw InputError("SLURM_ARRAY_TASK_ID = '" + text +
                       "' is not a task index (a non-negative integer)");
    }
    from = "SLURM_ARRAY_TASK_ID = " + text;
  } else {
    return std::nullopt;
  }
  const std::size_t n = manifest.cases.size();
  if (index < 0 || static_cast<std::size_t>(index) >= n) {
    throw InputError(fmt::format("{}: {} is not a case: the manifest has {} case{} (tasks 0-{})",
                                 manifest.path, from, n, n == 1 ? "" : "s", n - 1));
  }
  return static_cast<std::size_t>(index);
}

int run_batch(const BatchManifest& manifest, std::optional<std::size_t> task,
              const BatchCaseRunner& run_case, bool quiet) {
  const std::size_t n = manifest.cases.size();
  std::vector<std::size_t> selected;
  if (task) {
    selected.push_back(*task);
  } else {
    for (std::size_t i = 0; i < n; ++i) selected.push_back(i);
  }
  std::vector<CaseOutcome> outcomes;
  for (const std::size_t i : selected) {
    const BatchCase& c = manifest.cases[i];
    if (!quiet) {
      fmt::print("== case {} of {} ({}): {} -> {}\n", i, n, manifest.path, c.case_path, c.out_dir);
      std::fflush(stdout);
    }
    outcomes.push_back(run_isolated(c, run_case));
  }

  std::size_t failed = 0;
  for (const CaseOutcome& o : outcomes)
    failed += o.exit_status != 0 || o.signal || !o.error.empty();
  if (!quiet) {
    fmt::print("batch {}: {} of {} case{} registered, {} failed\n", manifest.path,
               selected.size() - failed, selected.size(), selected.size() == 1 ? "" : "s", failed);
    for (std::size_t k = 0; k < selected.size(); ++k) {
      const BatchCase& c = manifest.cases[selected[k]];
      fmt::print("  [{}] {} ({:.1f} s): {} -> {}\n", selected[k], describe(outcomes[k]),
                 outcomes[k].seconds, c.case_path, c.out_dir);
    }
    std::fflush(stdout);
  }
  for (std::size_t k = 0; k < selected.size(); ++k) {
    const CaseOutcome& o = outcomes[k];
    if (o.exit_status == 0 && !o.signal && o.error.empty()) continue;
    std::cerr << "sinew-register: " << manifest.path << ": case " << selected[k] << " ("
              << manifest.cases[selected[k]].case_path << "): " << describe(o) << "\n";
  }
  if (task) {
    const CaseOutcome& o = outcomes.front();
    return o.signal || !o.error.empty() ? 1 : o.exit_status;
  }
  return failed == 0 ? 0 : 1;
}

}  // namespace sinew::tools
