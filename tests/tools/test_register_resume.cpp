// sinew-register's checkpoints and --resume, end to end (issue 7, "long runs"): a run killed with
// SIGKILL at several moments — while the initial fit runs, right after it, in the middle of the
// last stage — and resumed with --resume OUTDIR ends with the outputs of an uninterrupted run
// (to 1e-9 relative; in practice bit for bit); a killed run leaves nothing that looks finished;
// and --resume without a checkpoint, or against a case that changed, is a one-line error, exit 2.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <iostream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "tests/support/run_tool.hpp"
#include "tools/register/demo_case.hpp"

extern char** environ;

namespace {

namespace fs = std::filesystem;
using sinew::testing::read_text;
using sinew::testing::run_tool;
using sinew::testing::scratch_dir;
using sinew::testing::write_text;

const std::string kTool = std::string(SINEW_BINARY_DIR) + "/tools/sinew-register";
constexpr double kRelative = 1e-9;

// The demo capsule (1,334 tets) with landmarks besides its ICP markers, so that two stages run
// (attachments stop at once: with β = 0 the constant fit leaves nothing to do there), and stop
// rules that let each stage use all its iterations: about 0.4 s per iteration, 2 s initial fit.
// Without its attachments it is a free object (landmarks → ICP markers, rigid frame from x).
fs::path write_case(const fs::path& dir, bool free_object, int max_iterations) {
  const sinew::tools::DemoCase demo = sinew::tools::make_demo_case();
  sinew::tools::write_demo_case(demo, dir.string());
  nlohmann::json c = nlohmann::json::parse(read_text(dir / "case.json"));
  nlohmann::json landmarks = nlohmann::json::array();
  for (Eigen::Index v = 7; v < demo.template_surface.vertices.rows(); v += 53) {
    const Eigen::Vector3d p = demo.template_surface.vertices.row(v).transpose();
    const Eigen::Vector3d q = demo.truth_surface.vertices.row(v).transpose();
    landmarks.push_back({{"template", {p.x(), p.y(), p.z()}}, {"target", {q.x(), q.y(), q.z()}}});
  }
  c["landmarks"] = landmarks;
  // sinew-register fits landmarks inside the ICP stage by default; the separate landmark stage
  // keeps a stage boundary to be killed across.
  c["weights"]["landmark_stage"] = true;
  // The uniform 1,334-tet mesh the stop rules were set for: on the tool's default thickness-sized
  // mesh (1,525 tets) the landmark stage ends by its small-decrease test one iteration early.
  c["mesh"]["tets_across_thickness"] = 0;
  c["stop"] = {{"max_iterations", max_iterations},
               {"max_marker_error", 1e-9},
               {"min_step", 0.0},
               {"no_progress_iterations", 0}};
  if (free_object) c.erase("attachments");
  write_text(dir / "case.json", c.dump(1));
  return dir / "case.json";
}

// A sinew-register started in the background (posix_spawn), its output in files.
struct Child {
  pid_t pid = -1;
};

Child spawn_tool(const std::vector<std::string>& args, const fs::path& log) {
  std::vector<char*> argv;
  std::vector<std::string> storage = args;
  storage.insert(storage.begin(), kTool);
  for (std::string& a : storage) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  Child child;
  const int status =
      posix_spawn(&child.pid, kTool.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (status != 0) child.pid = -1;
  return child;
}

// Polls OUTDIR/checkpoint.sinew until moment(checkpoint) holds, then SIGKILLs the child. Every
// checkpoint seen must parse: it is replaced atomically. Returns the last checkpoint read
// before the kill (the run may have written a later one in between), or null on a timeout.
nlohmann::json kill_when(Child child, const fs::path& out,
                         const std::function<bool(const nlohmann::json&)>& moment) {
  const fs::path file = out / "checkpoint.sinew";
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  nlohmann::json seen;
  while (std::chrono::steady_clock::now() < deadline) {
    if (fs::exists(file)) {
      const std::string text = read_text(file);
      if (!text.empty()) {
        seen = nlohmann::json::parse(text, nullptr, false);
        EXPECT_FALSE(seen.is_discarded()) << "a torn checkpoint: " << text.substr(0, 200);
        if (!seen.is_discarded() && moment(seen)) {
          kill(child.pid, SIGKILL);
          int status = 0;
          waitpid(child.pid, &status, 0);
          // Killed, not finished before the signal arrived.
          EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << status;
          return seen;
        }
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  kill(child.pid, SIGKILL);
  waitpid(child.pid, nullptr, 0);
  ADD_FAILURE() << "the moment to kill never came";
  return nlohmann::json();
}

std::vector<double> obj_vertices(const fs::path& path) {
  std::vector<double> out;
  std::istringstream in(read_text(path));
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("v ", 0) != 0) continue;
    std::istringstream s(line.substr(2));
    double x = 0, y = 0, z = 0;
    s >> x >> y >> z;
    out.insert(out.end(), {x, y, z});
  }
  return out;
}

// Every number of the VTU file (points, Fp, stretches, det Fp, and the connectivity).
std::vector<double> vtu_numbers(const fs::path& path) {
  std::string text = read_text(path);
  for (char& ch : text)
    if (ch == '<' || ch == '>' || ch == '"' || ch == '=') ch = ' ';
  std::vector<double> out;
  std::istringstream in(text);
  for (std::string token; in >> token;) {
    char* end = nullptr;
    const double v = std::strtod(token.c_str(), &end);
    if (end == token.c_str() + token.size() && !token.empty()) out.push_back(v);
  }
  return out;
}

// Largest |a − b| / scale over two equally long lists (scale: their largest magnitude).
double max_relative_difference(const std::vector<double>& a, const std::vector<double>& b) {
  EXPECT_EQ(a.size(), b.size());
  double scale = 0.0;
  for (double v : a) scale = std::max(scale, std::abs(v));
  double worst = 0.0;
  for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i)
    worst = std::max(worst, std::abs(a[i] - b[i]) / scale);
  return worst;
}

double relative(double a, double b) {
  return std::abs(a - b) / std::max(std::abs(a), 1e-300);
}

// The resumed folder's outputs against the uninterrupted run's; the largest relative difference.
double compare_outputs(const fs::path& uninterrupted, const fs::path& resumed) {
  const std::vector<double> surface_a = obj_vertices(uninterrupted / "result_surface.obj");
  EXPECT_GT(surface_a.size(), 1000u);
  double worst = max_relative_difference(surface_a, obj_vertices(resumed / "result_surface.obj"));
  const std::vector<double> vtu_a = vtu_numbers(uninterrupted / "result.vtu");
  EXPECT_GT(vtu_a.size(), 20000u);
  worst = std::max(worst, max_relative_difference(vtu_a, vtu_numbers(resumed / "result.vtu")));
  const auto a = nlohmann::json::parse(read_text(uninterrupted / "report.json"));
  const auto b = nlohmann::json::parse(read_text(resumed / "report.json"));
  EXPECT_EQ(a["termination"], b["termination"]);
  EXPECT_EQ(a["final"]["stage"], b["final"]["stage"]);
  for (const char* key :
       {"objective", "initial_objective", "marker_error_mean", "marker_error_max"})
    worst = std::max(worst, relative(a["final"][key].get<double>(), b["final"][key].get<double>()));
  // The same iterations with the same objectives and steps, and the same equilibrium solves.
  EXPECT_EQ(a["iterations"].size(), b["iterations"].size());
  for (std::size_t i = 0; i < std::min(a["iterations"].size(), b["iterations"].size()); ++i) {
    const auto& p = a["iterations"][i];
    const auto& q = b["iterations"][i];
    EXPECT_EQ(p["stage"], q["stage"]) << i;
    EXPECT_EQ(p["iteration"], q["iteration"]) << i;
    EXPECT_EQ(p["equilibrium_solves"], q["equilibrium_solves"]) << i;
    worst = std::max(worst, relative(p["objective"].get<double>(), q["objective"].get<double>()));
    worst = std::max(worst, relative(p["step"].get<double>(), q["step"].get<double>()));
  }
  EXPECT_EQ(a["totals"]["equilibrium_solves"], b["totals"]["equilibrium_solves"]);
  EXPECT_EQ(a["resumes"], 0);
  EXPECT_EQ(b["resumes"], 1);
  return worst;
}

// A finished folder: the three results, no checkpoint.
void expect_finished(const fs::path& out) {
  for (const char* name : {"report.json", "result_surface.obj", "result.vtu"})
    EXPECT_TRUE(fs::exists(out / name)) << out / name;
  EXPECT_FALSE(fs::exists(out / "checkpoint.sinew")) << out;
}

// A killed folder: a checkpoint and nothing that looks like a result.
void expect_killed(const fs::path& out) {
  EXPECT_TRUE(fs::exists(out / "checkpoint.sinew")) << out;
  for (const char* name : {"report.json", "result_surface.obj", "result.vtu"})
    EXPECT_FALSE(fs::exists(out / name)) << out / name;
}

struct Moment {
  std::string name;
  std::function<bool(const nlohmann::json&)> reached;
  // The line --resume prints for the checkpoint it found.
  std::function<std::string(const nlohmann::json&)> resume_line;
};

std::string resuming_at(const nlohmann::json& checkpoint) {
  const nlohmann::json& state = checkpoint["state"];
  return "resuming at stage " + state["next_stage"].get<std::string>() + " iteration " +
         std::to_string(state["next_iteration"].get<int>()) + " (" +
         std::to_string(state["iterations"].size()) + " iterations done";
}

void kill_and_resume(const fs::path& dir, const fs::path& case_file, int max_iterations,
                     const std::vector<Moment>& moments) {
  // Uninterrupted.
  const auto start = std::chrono::steady_clock::now();
  const auto a = run_tool(
      kTool + " --case " + case_file.string() + " --out " + (dir / "uninterrupted").string(), dir);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::cout << a.out;
  ASSERT_EQ(a.exit_status, 0) << a.err << a.out;
  expect_finished(dir / "uninterrupted");
  // The progress lines estimate the time left, as an upper bound.
  EXPECT_NE(a.out.find(" left"), std::string::npos) << a.out;
  EXPECT_NE(a.out.find("  at most "), std::string::npos) << a.out;
  const auto report = nlohmann::json::parse(read_text(dir / "uninterrupted" / "report.json"));
  // The stop rules let the stages run to their limits: every kill moment below is mid-run.
  EXPECT_EQ(report["termination"], "max-iterations") << report.dump(1);
  EXPECT_EQ(report["iterations"].size(), static_cast<std::size_t>(1 + 2 * max_iterations));
  std::cout << "uninterrupted: " << seconds << " s\n";

  double worst = 0.0;
  for (const Moment& moment : moments) {
    SCOPED_TRACE(moment.name);
    const fs::path out = dir / ("killed_" + moment.name);
    const Child child = spawn_tool({"--case", case_file.string(), "--out", out.string()},
                                   dir / ("killed_" + moment.name + ".log"));
    ASSERT_GT(child.pid, 0);
    const nlohmann::json seen = kill_when(child, out, moment.reached);
    ASSERT_TRUE(seen.is_object());
    expect_killed(out);
    // What --resume will start from: the checkpoint on disk now (at or after `seen`).
    const auto on_disk = nlohmann::json::parse(read_text(out / "checkpoint.sinew"));
    EXPECT_EQ(on_disk["format"], "sinew-register checkpoint");
    if (on_disk["state"].is_object()) {
      // s and x as hex floats, bit-exact.
      const std::string x0 = on_disk["state"]["x"][0].get<std::string>();
      EXPECT_TRUE(x0.rfind("0x", 0) == 0 || x0.rfind("-0x", 0) == 0) << x0;
    }
    const auto r = run_tool(kTool + " --resume " + out.string(), dir);
    std::cout << "-- killed " << moment.name << ", resumed:\n" << r.out;
    ASSERT_EQ(r.exit_status, 0) << r.err << r.out;
    EXPECT_NE(r.out.find(moment.resume_line(on_disk)), std::string::npos)
        << moment.resume_line(on_disk) << "\n"
        << r.out;
    expect_finished(out);
    const double difference = compare_outputs(dir / "uninterrupted", out);
    std::cout << "killed " << moment.name << ": max relative difference to the uninterrupted run "
              << difference << "\n";
    EXPECT_LE(difference, kRelative);
    worst = std::max(worst, difference);
  }
  std::cout << "max relative difference over the kill moments: " << worst << "\n";
}

bool has_state(const nlohmann::json& c) {
  return c["state"].is_object();
}

TEST(RegisterResume, AttachedRunKilledAtThreeMomentsResumesToTheUninterruptedResult) {
  const auto dir = scratch_dir("register_resume_attached");
  const int max_iterations = 6;
  const fs::path case_file = write_case(dir / "case", false, max_iterations);
  const std::vector<Moment> moments = {
      // The run has started (the checkpoint names the case) but the initial fit is not done.
      {"during_initial_fit", [](const nlohmann::json& c) { return c["state"].is_null(); },
       [](const nlohmann::json&) {
         return std::string(
             "resuming: the run stopped before its initial fit was done; registering from the "
             "start");
       }},
      // Just after the initial fit, before the first Gauss–Newton iteration's checkpoint.
      {"after_initial_fit",
       [](const nlohmann::json& c) {
         return has_state(c) && c["state"]["iterations"].size() == 1u;
       },
       resuming_at},
      // In the middle of the last (ICP) stage.
      {"mid_icp_stage",
       [](const nlohmann::json& c) {
         return has_state(c) && c["state"]["next_stage"] == "icp" &&
                c["state"]["next_iteration"].get<int>() >= 3;
       },
       resuming_at},
  };
  kill_and_resume(dir, case_file, max_iterations, moments);
}

TEST(RegisterResume, FreeRunKilledMidStageResumesToTheUninterruptedResult) {
  // No attachments: the rigid frame of eqs. 19–20 comes from x, so it survives a restart too.
  const auto dir = scratch_dir("register_resume_free");
  const int max_iterations = 4;
  const fs::path case_file = write_case(dir / "case", true, max_iterations);
  const std::vector<Moment> moments = {
      {"mid_landmark_stage",
       [](const nlohmann::json& c) {
         return has_state(c) && c["state"]["next_stage"] == "landmarks" &&
                c["state"]["next_iteration"].get<int>() >= 2;
       },
       resuming_at},
  };
  kill_and_resume(dir, case_file, max_iterations, moments);
}

TEST(RegisterResume, ResumeWithoutACheckpointOrAgainstAnotherCaseIsAOneLineError) {
  const auto dir = scratch_dir("register_resume_errors");
  const fs::path case_file = write_case(dir / "case", false, 3);
  const fs::path free_case = write_case(dir / "free", true, 3);
  const auto one_line_error = [&](const std::string& args, const std::string& expected) {
    const auto r = run_tool(kTool + " " + args, dir);
    EXPECT_EQ(r.exit_status, 2) << r.err << r.out;
    EXPECT_EQ(r.err, "sinew-register: " + expected + "\n");
    return r;
  };

  // A folder without a checkpoint: empty, missing, or a finished run's.
  fs::create_directories(dir / "empty");
  one_line_error("--resume " + (dir / "empty").string(),
                 (dir / "empty/checkpoint.sinew").string() +
                     ": no checkpoint to resume from (the run finished, see report.json, or this "
                     "is not a sinew-register output folder)");
  one_line_error("--resume " + (dir / "nope").string(),
                 (dir / "nope/checkpoint.sinew").string() +
                     ": no checkpoint to resume from (the run finished, see report.json, or this "
                     "is not a sinew-register output folder)");
  EXPECT_FALSE(fs::exists(dir / "nope"));
  const auto finished =
      run_tool(kTool + " --case " + case_file.string() + " --out " + (dir / "done").string(), dir);
  ASSERT_EQ(finished.exit_status, 0) << finished.err;
  expect_finished(dir / "done");
  one_line_error("--resume " + (dir / "done").string(),
                 (dir / "done/checkpoint.sinew").string() +
                     ": no checkpoint to resume from (the run finished, see report.json, or this "
                     "is not a sinew-register output folder)");

  // A killed run's checkpoint (right after the initial fit).
  const fs::path killed = dir / "killed";
  const Child child =
      spawn_tool({"--case", case_file.string(), "--out", killed.string()}, dir / "killed.log");
  ASSERT_GT(child.pid, 0);
  ASSERT_TRUE(kill_when(child, killed, has_state).is_object());
  expect_killed(killed);
  const std::string checkpoint = read_text(killed / "checkpoint.sinew");
  const std::string checkpoint_path = (killed / "checkpoint.sinew").string();

  // ... pointed at another case (the same capsule without attachments: a free object).
  nlohmann::json other = nlohmann::json::parse(checkpoint);
  other["case"] = free_case.string();
  other["case_file"] = free_case.string();
  write_text(killed / "checkpoint.sinew", other.dump());
  one_line_error("--resume " + killed.string(),
                 checkpoint_path + ": does not match " + free_case.string() +
                     " as it is now (mode: attached in the checkpoint, free now): the case, its "
                     "template or its markers changed since the run started; start it again "
                     "with --case");
  expect_killed(killed);

  // ... after the case's markers changed (one ICP marker less).
  write_text(killed / "checkpoint.sinew", checkpoint);
  const std::string markers = read_text(dir / "case/markers.csv");
  std::string fewer = markers.substr(0, markers.rfind('\n', markers.size() - 2) + 1);
  write_text(dir / "case/markers.csv", fewer);
  one_line_error("--resume " + killed.string(),
                 checkpoint_path + ": does not match " + case_file.string() +
                     " as it is now (icp_markers: 80 in the checkpoint, 79 now): the case, its "
                     "template or its markers changed since the run started; start it again "
                     "with --case");
  write_text(dir / "case/markers.csv", markers);

  // ... after the template changed (one vertex moved by 1 mm: another tet mesh).
  const std::string template_obj = read_text(dir / "case/template.obj");
  {
    std::istringstream in(template_obj);
    std::ostringstream out;
    bool moved = false;
    for (std::string line; std::getline(in, line);) {
      if (!moved && line.rfind("v ", 0) == 0) {
        std::istringstream s(line.substr(2));
        double x = 0, y = 0, z = 0;
        s >> x >> y >> z;
        out << "v " << x - 1.0 << " " << y << " " << z << "\n";
        moved = true;
      } else {
        out << line << "\n";
      }
    }
    write_text(dir / "case/template.obj", out.str());
  }
  const auto changed = run_tool(kTool + " --resume " + killed.string(), dir);
  EXPECT_EQ(changed.exit_status, 2) << changed.err << changed.out;
  EXPECT_EQ(std::count(changed.err.begin(), changed.err.end(), '\n'), 1) << changed.err;
  EXPECT_EQ(changed.err.rfind("sinew-register: " + checkpoint_path + ": does not match " +
                                  case_file.string() + " as it is now (",
                              0),
            0u)
      << changed.err;
  // The mesh is what differs (its vertex or tet count, else its hash), not just the markers.
  EXPECT_TRUE(changed.err.find("(tet_vertices: ") != std::string::npos ||
              changed.err.find("(tets: ") != std::string::npos ||
              changed.err.find("(mesh_hash: ") != std::string::npos)
      << changed.err;
  write_text(dir / "case/template.obj", template_obj);
  expect_killed(killed);

  // ... damaged (cut short).
  write_text(killed / "checkpoint.sinew", checkpoint.substr(0, checkpoint.size() / 2));
  const auto damaged = run_tool(kTool + " --resume " + killed.string(), dir);
  EXPECT_EQ(damaged.exit_status, 2) << damaged.err;
  EXPECT_EQ(std::count(damaged.err.begin(), damaged.err.end(), '\n'), 1) << damaged.err;
  EXPECT_EQ(damaged.err.rfind("sinew-register: " + checkpoint_path + ":1:", 0), 0u) << damaged.err;
  EXPECT_NE(damaged.err.find("invalid JSON"), std::string::npos) << damaged.err;
  // ... not a checkpoint at all.
  write_text(killed / "checkpoint.sinew", "{\"format\": \"something else\"}\n");
  one_line_error("--resume " + killed.string(),
                 checkpoint_path +
                     ":1:12: format is not 'sinew-register checkpoint' (not a sinew-register "
                     "checkpoint, or a damaged one)");

  // The original checkpoint, unchanged case: resumes to the end.
  write_text(killed / "checkpoint.sinew", checkpoint);
  const auto resumed = run_tool(kTool + " --resume " + killed.string() + " --quiet", dir);
  EXPECT_EQ(resumed.exit_status, 0) << resumed.err;
  EXPECT_EQ(resumed.out, "");
  expect_finished(killed);

  // --resume takes no --case, --out, --truth or --max-iterations: the checkpoint names them.
  one_line_error("--resume " + killed.string() + " --max-iterations 2",
                 "--resume OUTDIR takes only --quiet (the checkpoint names the case, --truth and "
                 "--max-iterations of the run)");
  one_line_error("--resume " + killed.string() + " --case " + case_file.string(),
                 "--resume OUTDIR takes only --quiet (the checkpoint names the case, --truth and "
                 "--max-iterations of the run)");
}

TEST(RegisterResume, ANewRunRemovesAnEarlierRunsResultsFirst) {
  // A run started into a finished run's folder and killed must not leave the old results there
  // looking like its own.
  const auto dir = scratch_dir("register_resume_rerun");
  const fs::path case_file = write_case(dir / "case", false, 2);
  const fs::path out = dir / "out";
  const auto first =
      run_tool(kTool + " --case " + case_file.string() + " --out " + out.string(), dir);
  ASSERT_EQ(first.exit_status, 0) << first.err;
  expect_finished(out);
  const Child child =
      spawn_tool({"--case", case_file.string(), "--out", out.string()}, dir / "log");
  ASSERT_GT(child.pid, 0);
  ASSERT_TRUE(kill_when(child, out, [](const nlohmann::json&) { return true; }).is_object());
  expect_killed(out);
}

}  // namespace
