#pragma once
/// sinew-register --batch: many registration cases from one manifest, one output folder each,
/// either all in turn (continuing past failures, then a summary) or one Slurm array task.
///
/// Manifest (keys other than these are errors; paths relative to the manifest's folder):
/// {
///   "cases": [
///     {"case": "liver/case.json", "out": "results/liver"},
///     {"case": "kidney/case.json", "out": "results/kidney", "truth": "kidney/truth.obj"}
///   ]
/// }
/// "case" and "out" are required, "truth" (sinew-register --truth) is optional; no two cases may
/// share an output folder. Each case runs in a child process of its own (fork), so a case that
/// fails, even by crashing, does not stop the others.
///
/// Task selection: --task N, else the environment variable SLURM_ARRAY_TASK_ID, picks case N
/// (0-based, in manifest order) alone: `sbatch --array=0-(n-1)` runs the manifest one case per
/// task (examples/slurm/register_array.sbatch). Without either, every case runs.
///
/// Exit status: 0 every selected case registered; 1 at least one case failed (its own status is in
/// the summary: 1 registration failed, 2 bad input, or a signal); 2 bad manifest or usage. With a
/// task selected, the status is that case's own (a signal gives 1).

#include <cstddef>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

namespace sinew::tools {

/// One case of a manifest, paths resolved against the manifest's folder.
struct BatchCase {
  std::string case_path;
  std::string out_dir;
  std::string truth_path;  ///< "" when the case has no "truth"
};

struct BatchManifest {
  std::string path;
  std::vector<BatchCase> cases;  ///< at least one
};

/// Reads and validates a manifest. Throws InputError (tools/io/json_file.hpp), one line naming the
/// file, the line and column and the field ("batch.json:4:12: cases[2].out ..."). The case files
/// are not opened here: a missing one fails its own case only.
BatchManifest read_batch_manifest(const std::string& path);
/// The same for a parsed document; path names it and resolves the cases' relative names.
BatchManifest parse_batch_manifest(const nlohmann::json& doc, const std::string& path);

/// The case to run alone: `task` (--task) when given, else SLURM_ARRAY_TASK_ID (`slurm_task`, null
/// when unset), else std::nullopt (all cases). Throws InputError when the value is not a
/// non-negative integer or is not below the manifest's number of cases.
std::optional<std::size_t> select_batch_task(const BatchManifest& manifest,
                                             std::optional<long> task, const char* slurm_task);

/// Runs one case in the child process; returns its exit status (0, 1 or 2 as sinew-register).
using BatchCaseRunner = std::function<int(const BatchCase&)>;

/// Runs the selected case (task) or every case, each in a forked child calling `run_case`, prints a
/// header line before each case (unless quiet) and a summary, and returns the exit status above.
int run_batch(const BatchManifest& manifest, std::optional<std::size_t> task,
              const BatchCaseRunner& run_case, bool quiet);

}  // namespace sinew::tools
