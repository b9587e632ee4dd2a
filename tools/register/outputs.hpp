#pragma once
/// sinew-register's outputs from an offline::register_case result: OUTDIR's files (result surface
/// in OBJ and the template's format, result.vtu, transferred surfaces, slice pictures, PNG plots)
/// and report.json's content. The computation is in offline/registration/register_case.hpp; this
/// is the file side of it.
#include <fmt/core.h>

#include <nlohmann/json.hpp>

#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "offline/io/surface_mesh_io.hpp"
#include "offline/io/volume_image_io.hpp"
#include "offline/registration/register_case.hpp"

namespace sinew::tools {

/// Lines on stdout unless --quiet.
class Log {
 public:
  explicit Log(bool quiet) : quiet_(quiet) {}
  template <typename... Args>
  void line(fmt::format_string<Args...> format, Args&&... args) const {
    if (quiet_) return;
    fmt::print(format, std::forward<Args>(args)...);
    std::fputc('\n', stdout);
    std::fflush(stdout);
  }

 private:
  bool quiet_;
};

/// OUTDIR's files.
struct RegisterOutputs {
  std::filesystem::path dir;
  std::filesystem::path surface() const { return dir / "result_surface.obj"; }
  std::filesystem::path vtu() const { return dir / "result.vtu"; }
  std::filesystem::path report() const { return dir / "report.json"; }
};

/// Creates OUTDIR (after every input check) and proves it writable before the long run; removes
/// an earlier run's results there, so that a run killed from now on leaves nothing that looks
/// finished (report.json is written last). Throws InputError.
void prepare_output_dir(const RegisterOutputs& out, const offline::RegistrationCase& c);

/// --truth FILE (shown as given_as in messages): std::nullopt when file is empty; throws InputError
/// when it cannot be read.
std::optional<offline::io::SurfaceMesh> read_truth(const std::string& file,
                                                   const std::string& given_as, const Log& log);

/// The case's "scan_image" (and mask), read before any work so that a bad image fails early.
struct ScanImages {
  std::optional<offline::io::VolumeImage> image, mask;
};
ScanImages read_scan_images(const offline::RegistrationCase& c, const Log& log);

/// report.json without "truth", "slices", "outputs" and "totals": the case, inputs, options,
/// per-iteration log, termination, final figures, coverage and mesh quality.
nlohmann::json registration_report(const offline::RegistrationCase& c,
                                   const offline::RegisterCaseResult& r,
                                   const std::string& case_path, int resumes);

/// report.json's "truth" (--truth FILE, given as truth_path), logged.
nlohmann::json truth_report(const offline::io::SurfaceMesh& result,
                            const offline::io::SurfaceMesh& truth, const std::string& truth_path,
                            double diagonal, const std::string& unit, const Log& log);

/// Writes the result files of a usable registration (each atomically) and returns their paths;
/// sets report["slices"] when the case has a scan image. Throws std::runtime_error when a file
/// cannot be written.
std::vector<std::string> write_result_files(const RegisterOutputs& out,
                                            const offline::RegistrationCase& c,
                                            const offline::RegisterCaseResult& r,
                                            const ScanImages& scan, nlohmann::json& report,
                                            const Log& log);

/// Completes report.json with "outputs" (written) and "totals" (iterations, equilibrium solves,
/// seconds per phase: reading_seconds before register_case, writing_seconds after it) and writes
/// it, last, to OUTDIR/report.json (appended to written).
void write_report(const RegisterOutputs& out, const offline::RegisterCaseResult& r,
                  double reading_seconds, double writing_seconds, double total_seconds,
                  nlohmann::json& report, std::vector<std::string>& written);

}  // namespace sinew::tools
