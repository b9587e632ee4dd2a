#include "tools/batch/child_processes.hpp"

#include <fmt/core.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <iostream>
#include <map>
#include <vector>

#include "tools/io/json_file.hpp"

namespace sinew::tools {
namespace {

using Clock = std::chrono::steady_clock;

// In the child: the body, its exceptions turned into exit status 2, and no return to the caller.
[[noreturn]] void child_main(std::size_t item, const std::string& program, const ChildBody& body,
                             pid_t parent) {
  // Die with the parent: a batch killed with SIGKILL must not leave children writing its outputs.
  prctl(PR_SET_PDEATHSIG, SIGKILL);
  if (getppid() != parent) _exit(1);  // the parent died before prctl
  int status = 1;
  try {
    status = body(item);
  } catch (const std::exception& e) {
    std::cerr << program << ": " << e.what() << "\n";
    status = 2;
  } catch (...) {
    std::cerr << program << ": unknown error\n";
    status = 2;
  }
  std::cout.flush();
  std::cerr.flush();
  std::fflush(nullptr);
  _exit(status);  // no atexit handlers or static destructors of the parent's copy
}

void record_status(int raw, ChildOutcome& outcome) {
  if (WIFEXITED(raw)) {
    outcome.exit_status = WEXITSTATUS(raw);
  } else if (WIFSIGNALED(raw)) {
    outcome.exit_status = 1;
    outcome.signal = WTERMSIG(raw);
  }
}

}  // namespace

std::string describe_abnormal_end(const ChildOutcome& o) {
  if (!o.error.empty()) return "not run (" + o.error + ")";
  if (o.signal) return fmt::format("crashed (signal {}: {})", *o.signal, strsignal(*o.signal));
  return "";
}

void run_in_children(const std::vector<std::size_t>& items, int jobs, const std::string& program,
                     const ChildBody& body, const std::function<void(std::size_t)>& started,
                     const std::function<void(std::size_t, const ChildOutcome&)>& finished) {
  if (jobs < 1) jobs = 1;
  struct Running {
    std::size_t item;
    Clock::time_point start;
  };
  std::map<pid_t, Running> running;
  const pid_t self = getpid();
  std::size_t next = 0;
  while (next < items.size() || !running.empty()) {
    while (next < items.size() && static_cast<int>(running.size()) < jobs) {
      const std::size_t item = items[next++];
      if (started) started(item);
      std::fflush(nullptr);  // nothing buffered may be printed twice
      std::cout.flush();
      std::cerr.flush();
      const auto start = Clock::now();
      const pid_t pid = fork();
      if (pid == 0) child_main(item, program, body, self);
      if (pid < 0) {
        ChildOutcome o;
        o.error = std::string("fork failed: ") + std::strerror(errno);
        finished(item, o);
        continue;
      }
      running.emplace(pid, Running{item, start});
    }
    if (running.empty()) continue;
    int raw = 0;
    const pid_t pid = waitpid(-1, &raw, 0);
    if (pid < 0) {
      if (errno == EINTR) continue;
      // No child left to wait for (should not happen): report the rest as not run.
      const std::string why = std::string("waitpid failed: ") + std::strerror(errno);
      for (const auto& [p, r] : running) {
        ChildOutcome o;
        o.error = why;
        finished(r.item, o);
      }
      running.clear();
      continue;
    }
    const auto it = running.find(pid);
    if (it == running.end()) continue;  // not one of ours
    ChildOutcome o;
    record_status(raw, o);
    o.seconds = std::chrono::duration<double>(Clock::now() - it->second.start).count();
    const std::size_t item = it->second.item;
    running.erase(it);
    finished(item, o);
  }
}

std::optional<std::size_t> select_array_task(std::size_t count, const std::string& what,
                                             const std::string& noun, std::optional<long> task,
                                             const char* slurm_task) {
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
  if (index < 0 || static_cast<std::size_t>(index) >= count) {
    throw InputError(fmt::format("{}: {} is not a {}: the manifest has {} {}{} (tasks 0-{})", what,
                                 from, noun, count, noun, count == 1 ? "" : "s",
                                 count == 0 ? 0 : count - 1));
  }
  return static_cast<std::size_t>(index);
}

}  // namespace sinew::tools
