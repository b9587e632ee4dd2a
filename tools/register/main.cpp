// sinew-register: plastic-strain registration of a template organ to sparse scan markers (seed
// 003, Wang, Matcuk & Barbič): tet-mesh the template, embed the attachments, landmarks and the
// template's surface vertices in it, run the staged Gauss–Newton registration and write
//   OUTDIR/result_surface.obj  the deformed template surface (same vertices and triangles as the
//                              template surface; for a tet-mesh template, its boundary)
//   OUTDIR/result.vtu          the deformed tet mesh with per-tet Fp (9), principal stretches (3),
//                              their ratio (largest / smallest) and det Fp as cell data (ParaView)
//   OUTDIR/result_surface.EXT  the same in the template's own format when it is .off/.stl/.ply
//   OUTDIR/report.json         per-iteration log, totals, termination, inputs and mesh quality
//                              (smallest dihedral angles of the template and of the result)
//   OUTDIR/marker_errors.png   histogram of the final marker errors (seed 003 Fig. 16)
//   OUTDIR/convergence.png     objective and marker errors per iteration (Fig. 9)
//
//   sinew-register --case case.json --out OUTDIR [--quiet] [--max-iterations N] [--truth FILE]
//   sinew-register --resume OUTDIR [--quiet]
//   sinew-register --make-demo-case DIR
//   sinew-register --batch manifest.json [--task N] [--quiet] [--max-iterations N]
//
// --truth FILE (a surface in the case's units) reports the distances between the result surface
// and FILE (result vertices to FILE's surface and FILE's vertices to the result surface: mean and
// max), on the terminal and in report.json's "truth". --make-demo-case writes a case with a known
// answer (tools/register/demo_case.hpp: a capsule stretched and bent, ICP markers on the truth,
// DIR/truth_surface.obj) and exits; scripts/demo registers it. --batch runs the cases of a
// manifest, each in a process of its own, or only case N (--task N or SLURM_ARRAY_TASK_ID, for a
// Slurm job array): tools/register/batch.hpp.
//
// Checkpoints: OUTDIR/checkpoint.sinew is written when the registration starts and after every
// Gauss–Newton iteration (tools/register/checkpoint_file.hpp), and removed once report.json is
// written. --resume OUTDIR re-reads the case it names, checks that mesh, markers and options are
// the same, and continues from the last finished iteration to the outputs of an uninterrupted run.
//
// The case file is described in tools/register/case_file.hpp. The geometry is normalised (bounding-
// box centre at the origin, diagonal 1, unit material) so the defaults fit millimetres and metres;
// results are mapped back to the case's units.
// Exit status: 0 registered; 1 outputs written but the registration failed (report.json says
// why; no result files), or stalled (termination "stalled": the result files are written and one
// line on stderr says how far the markers are); 2 bad input or usage (one line on stderr naming
// the file, nothing written).
//
// The registration itself is offline::register_case (offline/registration/register_case.hpp);
// this file reads the inputs, keeps the checkpoint and writes the outputs
// (tools/register/outputs.hpp).
#include <fmt/core.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "common/timing.hpp"
#include "offline/io/surface_mesh_io.hpp"
#include "offline/registration/register_case.hpp"
#include "tools/io/json_file.hpp"
#include "tools/register/batch.hpp"
#include "tools/register/case_file.hpp"
#include "tools/register/checkpoint_file.hpp"
#include "tools/register/demo_case.hpp"
#include "tools/register/outputs.hpp"

namespace {

using namespace sinew;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using common::seconds_since;

// What to run: a case into OUTDIR, or the resumption of a checkpoint's run.
struct RunRequest {
  std::string case_path;  // --case as given: reported
  std::string case_file;  // the file read (case_path, or its absolute form on resume)
  std::string out_dir;
  bool quiet = false;
  std::optional<int> max_iterations;
  std::string truth_path;  // --truth as given: reported
  std::string truth_file;  // the file read
  std::optional<tools::RegisterCheckpoint> resume;
};

// The checkpoint of this run as it starts: the command line, and the state to resume from.
tools::RegisterCheckpoint first_checkpoint(const RunRequest& request) {
  tools::RegisterCheckpoint checkpoint;
  checkpoint.case_path = request.case_path;
  checkpoint.case_file = fs::absolute(request.case_file).string();
  checkpoint.truth_path = request.truth_path;
  checkpoint.truth_file =
      request.truth_file.empty() ? std::string() : fs::absolute(request.truth_file).string();
  checkpoint.max_iterations = request.max_iterations;
  if (request.resume) {
    checkpoint.resumes = request.resume->resumes + 1;
    checkpoint.state = request.resume->state;
  }
  return checkpoint;
}

int run(const RunRequest& request) {
  const Clock::time_point run_start = Clock::now();
  const tools::Log log(request.quiet);
  Clock::time_point start = Clock::now();
  log.line("reading {}", request.case_file);
  const tools::RegistrationCase c = tools::read_registration_case(request.case_file);
  // --truth, checked before any work.
  const auto truth = tools::read_truth(request.truth_file, request.truth_path, log);
  const tools::ScanImages scan = tools::read_scan_images(c, log);
  const double reading = seconds_since(start);

  // Every input is valid once the case is prepared: only then is OUTDIR created, and the
  // checkpoint marks the run as unfinished and resumable from the start.
  const tools::RegisterOutputs out{fs::path(request.out_dir)};
  const fs::path checkpoint_file = tools::checkpoint_path(out.dir);
  tools::RegisterCheckpoint checkpoint = first_checkpoint(request);
  offline::RegisterCaseOptions options;
  options.max_iterations = request.max_iterations;
  options.resuming = request.resume.has_value();
  options.resume = request.resume && request.resume->state ? &*request.resume->state : nullptr;
  offline::RegisterCaseHooks hooks;
  hooks.message = [&](const std::string& line) { log.line("{}", line); };
  hooks.prepared = [&](const offline::PreparedCase& p) {
    checkpoint.identification = tools::run_identification(p, c.solver.cholesky);
    if (request.resume) {
      tools::check_resumable(*request.resume, checkpoint.identification, p.free_object,
                             checkpoint_file, request.case_file);
    }
    tools::prepare_output_dir(out, c);
    tools::write_checkpoint(checkpoint_file, checkpoint);
  };
  hooks.checkpoint = [&](const offline::GaussNewtonCheckpoint& state) {
    checkpoint.state = state;
    tools::write_checkpoint(checkpoint_file, checkpoint);
  };
  const offline::RegisterCaseResult r = offline::register_case(c, options, hooks);

  // ---- outputs (each written atomically; the report last, so its presence means "done")
  start = Clock::now();
  nlohmann::json report = tools::registration_report(c, r, request.case_path, checkpoint.resumes);
  if (r.shape && truth) {
    report["truth"] = tools::truth_report(r.shape->surface, *truth, request.truth_path,
                                          r.problem.frame.scale, offline::to_string(c.units), log);
  }
  std::vector<std::string> written = tools::write_result_files(out, c, r, scan, report, log);
  tools::write_report(out, r, reading, seconds_since(start), seconds_since(run_start), report,
                      written);
  {
    std::error_code ec;  // done: nothing left to resume
    fs::remove(checkpoint_file, ec);
  }
  for (const std::string& path : written) log.line("wrote {}", path);
  const offline::GaussNewtonSummary& summary = r.registration.summary;
  if (summary.usable() && summary.failed()) {
    // A stall (issue 51): the result files are written to look at, the status says it failed.
    std::cerr << "sinew-register: " << request.case_path << ": " << summary.message << "\n";
  }
  return summary.failed() ? 1 : 0;
}

// One case with its errors reported: the exit status of the tool.
int run_reporting_errors(const RunRequest& request) {
  try {
    return run(request);
  } catch (const std::exception& e) {  // tools::InputError and anything unexpected alike
    std::cerr << "sinew-register: " << e.what() << "\n";
    return 2;
  }
}

int run_reporting_errors(const std::string& case_path, const std::string& out_dir, bool quiet,
                         std::optional<int> max_iterations, const std::string& truth_path) {
  RunRequest request;
  request.case_path = request.case_file = case_path;
  request.out_dir = out_dir;
  request.quiet = quiet;
  request.max_iterations = max_iterations;
  request.truth_path = request.truth_file = truth_path;
  return run_reporting_errors(request);
}

// --resume OUTDIR: the run of OUTDIR's checkpoint, continued.
int resume_reporting_errors(const std::string& out_dir, bool quiet) {
  RunRequest request;
  try {
    tools::RegisterCheckpoint checkpoint = tools::read_checkpoint(tools::checkpoint_path(out_dir));
    request.case_path = checkpoint.case_path;
    request.truth_path = checkpoint.truth_path;
    // The paths as given when they still name the same files from here (same working folder),
    // so that report.json reads as the uninterrupted run's.
    const auto same = [](const std::string& given, const std::string& absolute) {
      return !given.empty() && fs::absolute(given) == fs::path(absolute);
    };
    request.case_file = same(checkpoint.case_path, checkpoint.case_file) ? checkpoint.case_path
                                                                         : checkpoint.case_file;
    request.truth_file = same(checkpoint.truth_path, checkpoint.truth_file) ? checkpoint.truth_path
                                                                            : checkpoint.truth_file;
    request.out_dir = out_dir;
    request.quiet = quiet;
    request.max_iterations = checkpoint.max_iterations;
    request.resume = std::move(checkpoint);
  } catch (const std::exception& e) {
    std::cerr << "sinew-register: " << e.what() << "\n";
    return 2;
  }
  return run_reporting_errors(request);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Plastic-strain registration of a template organ to sparse scan markers (Sinew)"};
  std::string case_path, out_dir;
  bool quiet = false;
  std::optional<int> max_iterations;
  std::string truth_path, demo_dir, batch_path, resume_dir;
  std::optional<long> task;
  app.add_option("--case", case_path, "registration case (JSON)");
  app.add_option("--out", out_dir, "output folder (created)");
  app.add_option("--truth", truth_path,
                 "known target surface (.obj/.off/.stl/.ply, case units): report the result's "
                 "distance to it");
  app.add_option("--make-demo-case", demo_dir,
                 "write a case with a known answer (template.obj, markers.csv, attachments.json, "
                 "truth_surface.obj, case.json) into this folder and exit");
  app.add_option("--batch", batch_path,
                 "run the cases of a manifest (JSON: {\"cases\": [{\"case\": FILE, \"out\": "
                 "FOLDER}, ...]}), each into its own folder; see tools/register/batch.hpp");
  app.add_option("--task", task,
                 "with --batch: run case N of the manifest alone (0-based; default: "
                 "SLURM_ARRAY_TASK_ID when set, else every case)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--resume", resume_dir,
                 "continue the killed or interrupted run whose output folder this is, from its "
                 "checkpoint (OUTDIR/checkpoint.sinew), to the outputs of an uninterrupted run");
  app.add_flag("--quiet", quiet, "print nothing but errors");
  app.add_option("--max-iterations", max_iterations,
                 "Gauss-Newton iterations per stage (overrides stop.max_iterations)")
      ->check(CLI::Range(0, 100000));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  if (!demo_dir.empty()) {
    if (!case_path.empty() || !out_dir.empty() || !truth_path.empty() || !batch_path.empty() ||
        !resume_dir.empty()) {
      std::cerr << "sinew-register: --make-demo-case takes no --case, --out, --truth, --batch or "
                   "--resume\n";
      return 2;
    }
    try {
      const sinew::tools::DemoCase demo = sinew::tools::make_demo_case();
      sinew::tools::write_demo_case(demo, demo_dir);
      if (!quiet) fmt::print("{}\n", sinew::tools::demo_case_summary(demo, demo_dir));
      return 0;
    } catch (const std::exception& e) {
      std::cerr << "sinew-register: " << e.what() << "\n";
      return 2;
    }
  }
  if (!resume_dir.empty()) {
    if (!case_path.empty() || !out_dir.empty() || !truth_path.empty() || !batch_path.empty() ||
        max_iterations || task) {
      std::cerr << "sinew-register: --resume OUTDIR takes only --quiet (the checkpoint names the "
                   "case, --truth and --max-iterations of the run)\n";
      return 2;
    }
    return resume_reporting_errors(resume_dir, quiet);
  }
  if (!batch_path.empty()) {
    if (!case_path.empty() || !out_dir.empty() || !truth_path.empty()) {
      std::cerr << "sinew-register: --batch takes no --case, --out or --truth (the manifest names "
                   "them)\n";
      return 2;
    }
    try {
      const sinew::tools::BatchManifest manifest = sinew::tools::read_batch_manifest(batch_path);
      const auto selected =
          sinew::tools::select_batch_task(manifest, task, std::getenv("SLURM_ARRAY_TASK_ID"));
      return sinew::tools::run_batch(
          manifest, selected,
          [&](const sinew::tools::BatchCase& c) {
            return run_reporting_errors(c.case_path, c.out_dir, quiet, max_iterations,
                                        c.truth_path);
          },
          quiet);
    } catch (const std::exception& e) {
      std::cerr << "sinew-register: " << e.what() << "\n";
      return 2;
    }
  }
  if (task) {
    std::cerr << "sinew-register: --task applies to --batch only\n";
    return 2;
  }
  if (case_path.empty() || out_dir.empty()) {
    std::cerr << "sinew-register: --case and --out are required (or --make-demo-case DIR); see "
                 "--help\n";
    return 2;
  }
  return run_reporting_errors(case_path, out_dir, quiet, max_iterations, truth_path);
}
