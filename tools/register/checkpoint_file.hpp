#pragma once
/// sinew-register's checkpoint, OUTDIR/checkpoint.sinew: what `--resume OUTDIR` needs to finish a
/// killed run with the outputs of an uninterrupted one. JSON: the command line's case, --truth and
/// --max-iterations; the run's identification (mode, tet mesh and marker counts and hashes,
/// options), compared with the re-read case before resuming; and, once the initial fit is done,
/// the offline::GaussNewtonCheckpoint of the last finished iteration with every double written as
/// a C99 hex float ("%a"), so that s and x are restored bit for bit. Written atomically after every
/// iteration (temporary file in OUTDIR, fsync, rename); removed when report.json is written.
#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

#include "offline/registration/gauss_newton.hpp"
#include "offline/registration/register_case.hpp"

namespace sinew::tools {

struct RegisterCheckpoint {
  std::string case_path;              ///< --case as given (reported as is)
  std::string case_file;              ///< the same, absolute (re-read on resume)
  std::string truth_path;             ///< --truth as given, or empty
  std::string truth_file;             ///< the same, absolute
  std::optional<int> max_iterations;  ///< --max-iterations
  int resumes = 0;                    ///< how often the run was resumed before
  /// Mode, mesh, markers and options of the run (RegisterCheckpoint::mismatch compares them).
  nlohmann::json identification;
  /// The registration's state; empty while the first equilibrium and the initial fit run (a
  /// resume then registers from the start).
  std::optional<offline::GaussNewtonCheckpoint> state;
};

/// OUTDIR/checkpoint.sinew.
std::filesystem::path checkpoint_path(const std::filesystem::path& out_dir);

/// Writes atomically and durably: OUTDIR/checkpoint.sinew.tmp<pid>, fsync, rename, fsync of the
/// folder. Throws std::runtime_error (one line) on failure.
void write_checkpoint(const std::filesystem::path& path, const RegisterCheckpoint& checkpoint);

/// Reads a checkpoint; throws InputError with one line naming the file on any problem (missing,
/// not a sinew-register checkpoint, malformed field: with its line, column and path).
RegisterCheckpoint read_checkpoint(const std::filesystem::path& path);
/// The same for a parsed document named `file`; throws JsonValueError.
RegisterCheckpoint parse_checkpoint(const nlohmann::json& j, const std::string& file);

/// The first difference between a checkpoint's identification and the current run's, as
/// "tets: 1334 in the checkpoint, 1290 now"; std::nullopt when they are equal.
std::optional<std::string> identification_mismatch(const nlohmann::json& saved,
                                                   const nlohmann::json& now);

/// 64-bit FNV-1a of bytes, continuing from hash (start with kFnvOffset).
constexpr std::uint64_t kFnvOffset = 14695981039346656037ULL;
std::uint64_t fnv1a(const void* data, std::size_t bytes, std::uint64_t hash = kFnvOffset);

/// A double as a C99 hex float ("0x1.8p+1") and back (exact).
std::string hex_double(double value);

/// What a checkpoint must match to be resumed with a case: mode, mesh, markers, output surface and
/// options, as counts, 64-bit hashes (hex) and hex floats.
nlohmann::json run_identification(const offline::PreparedCase& p,
                                  offline::SparseCholeskyMethod cholesky);

/// Throws InputError "<checkpoint>: does not match <case> as it is now (...)" when the case's
/// identification (run_identification) or mode differs from the checkpoint's.
void check_resumable(const RegisterCheckpoint& saved, const nlohmann::json& identification,
                     bool free_object, const std::filesystem::path& checkpoint,
                     const std::string& case_path);

}  // namespace sinew::tools
