#pragma once
/// Work items run in child processes of their own (fork), one at a time or several at once, and
/// the Slurm job-array task selection: what sinew-register --batch and sinew-track --batch share.
/// A child that fails, even by crashing, does not stop the others; a child dies with its parent
/// (PR_SET_PDEATHSIG), so a batch killed halfway leaves no orphan writing into its outputs.

#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace sinew::tools {

/// How a child ended.
struct ChildOutcome {
  int exit_status = 1;        ///< the child's exit status (1 when it died of a signal)
  std::optional<int> signal;  ///< the signal that ended the child
  std::string error;          ///< set when the child could not be started (fork failed)
  double seconds = 0.0;       ///< wall time from fork to exit
  /// Exit status 0, no signal, started.
  bool ok() const { return exit_status == 0 && !signal && error.empty(); }
  /// The status a batch task reports for it: the child's own, 1 for a signal or no start.
  int task_status() const { return signal || !error.empty() ? 1 : exit_status; }
};

/// "crashed (signal 11: Segmentation fault)", "not run (fork failed: ...)", else "" (exited).
std::string describe_abnormal_end(const ChildOutcome& outcome);

/// The work of one item in the child; returns its exit status. An exception escaping it is printed
/// as "<program>: <what>" on stderr and gives exit status 2.
using ChildBody = std::function<int(std::size_t item)>;

/// Runs `body(item)` for every item in `items`, each in a forked child, at most `jobs` (>= 1) at
/// once, in order of `items`; `started(item)` (may be empty) is called in the parent just before
/// each fork and `finished(item, outcome)` as each child ends (in the order they end).
void run_in_children(const std::vector<std::size_t>& items, int jobs, const std::string& program,
                     const ChildBody& body, const std::function<void(std::size_t)>& started,
                     const std::function<void(std::size_t, const ChildOutcome&)>& finished);

/// The item to run alone in a Slurm job array: `task` (--task) when given, else
/// SLURM_ARRAY_TASK_ID (`slurm_task`, null when unset), else std::nullopt (all items). Throws
/// InputError when the value is not a non-negative integer or not below `count`; `what` names the
/// manifest and `noun` its items ("case", "video") in the message.
std::optional<std::size_t> select_array_task(std::size_t count, const std::string& what,
                                             const std::string& noun, std::optional<long> task,
                                             const char* slurm_task);

}  // namespace sinew::tools
