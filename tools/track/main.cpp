// sinew-track: tracks a beam-like object through a video and recovers the forces that bend it.
//   sinew-track --input <video | image | folder | pattern%04d.png> --init init.json --out
//   results.jsonl
//               [--overlay <folder | file.mp4>] [--stride K] [--first N] [--count M]
//               [--model beam|snake] [--truth truth.jsonl]
// One JSON line per processed frame: {"frame", "status", "nodes": [[x, y, θ]], "forces": [[fx, fy,
// m]], "rms_px", "verify_px", "iterations", "latency_us", ...}. Exit status: 0 done, 2 bad input.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <optional>

#include "rt/stabilisation.hpp"
#include "rt/tracker.hpp"
#include "rt/whisker/readout.hpp"
#include "tools/batch/child_processes.hpp"
#include "tools/io/beam_json.hpp"
#include "tools/track/batch.hpp"
#include "tools/track/frame_source.hpp"
#include "tools/track/overlay_sink.hpp"
#include "tools/track/track_init.hpp"
#include "tools/track/whiskers.hpp"

namespace {

using namespace sinew;

struct TruthFrame {
  Eigen::MatrixXd nodes;  // n x 3
  Eigen::MatrixXd loads;  // n x 3
  bool visible = true;
  double lambda = 0.0;  // P·L²/EI when the truth gives it
};

std::map<int, TruthFrame> read_truth(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw tools::InputError(path + ": cannot open file for reading");
  std::map<int, TruthFrame> truth;
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty()) continue;
    nlohmann::json j;
    try {
      j = nlohmann::json::parse(line);
    } catch (const nlohmann::json::exception& e) {
      throw tools::InputError(path + ":" + std::to_string(line_no) + ": invalid JSON");
    }
    const tools::JsonCursor c(j, path + ":" + std::to_string(line_no));
    TruthFrame t;
    const auto nodes = c.at("nodes");
    t.nodes.resize(nodes.array_size(), 3);
    t.loads = Eigen::MatrixXd::Zero(nodes.array_size(), 3);
    for (std::size_t i = 0; i < nodes.array_size(); ++i) {
      for (std::size_t k = 0; k < 3; ++k) t.nodes(i, k) = nodes.at(i).at(k).finite_number();
    }
    if (c.has("loads")) {
      const auto loads = c.at("loads");
      for (std::size_t i = 0; i < loads.array_size() && i < nodes.array_size(); ++i) {
        for (std::size_t k = 0; k < 3; ++k) t.loads(i, k) = loads.at(i).at(k).finite_number();
      }
    }
    if (c.has("visible")) t.visible = c.at("visible").boolean();
    if (c.has("lambda")) t.lambda = c.at("lambda").finite_number();
    truth[static_cast<int>(c.at("frame").integer())] = t;
  }
  return truth;
}

void draw_arrow(cv::Mat& img, const Eigen::Vector2d& from, const Eigen::Vector2d& vec,
                const cv::Scalar& colour) {
  const cv::Point2d a(from.x(), from.y()), b(from.x() + vec.x(), from.y() + vec.y());
  cv::arrowedLine(img, a, b, colour, 2, cv::LINE_AA, 0, 0.25);
}

void draw_overlay(cv::Mat& img, const rt::Tracker& tracker, const rt::FrameSummary& s, int frame) {
  const auto& model = tracker.model();
  const cv::Scalar curve_colour =
      s.status == rt::FrameStatus::kLost ? cv::Scalar(0, 0, 255) : cv::Scalar(0, 230, 255);
  for (int e = 0; e < model.num_elements(); ++e) {
    cv::Point2d prev;
    for (int k = 0; k <= 10; ++k) {
      const rt::CentrelinePoint p = tracker.centreline(e, k / 10.0);
      const cv::Point2d q(p.position.x(), p.position.y());
      if (k > 0) cv::line(img, prev, q, curve_colour, 2, cv::LINE_AA);
      prev = q;
    }
  }
  for (int i = 0; i < model.num_nodes(); ++i) {
    const Eigen::Vector2d x = tracker.node_position(i);
    cv::circle(img, cv::Point2d(x.x(), x.y()), 3, cv::Scalar(255, 255, 255), -1, cv::LINE_AA);
  }
  // Forces as arrows: directions, scaled so the largest is 60 px (the seed's Fig. 1 and 4).
  auto draw_forces = [&](const Eigen::VectorXd& f, const cv::Scalar& colour) {
    double fmax = 0.0;
    for (int i = 0; i < model.num_nodes(); ++i) fmax = std::max(fmax, f.segment<2>(3 * i).norm());
    if (!(fmax > 0.0)) return;
    for (int i = 0; i < model.num_nodes(); ++i) {
      const Eigen::Vector2d v = f.segment<2>(3 * i) * (60.0 / fmax);
      if (v.norm() > 2.0) draw_arrow(img, tracker.node_position(i), v, colour);
    }
  };
  if (!tracker.load_nodes().empty()) {
    draw_forces(tracker.fitted_loads(), cv::Scalar(60, 220, 60));
  } else {
    draw_forces(tracker.forces(), cv::Scalar(40, 40, 255));
  }
  char text[200];
  std::snprintf(text, sizeof text, "frame %d  %s  rms %.2f px  verify %.2f px  %.0f us", frame,
                rt::to_string(s.status), s.rms_px, s.verify_px, s.seconds * 1e6);
  cv::putText(img, text, cv::Point(10, 24), cv::FONT_HERSHEY_SIMPLEX, 0.6, cv::Scalar(0, 0, 0), 3,
              cv::LINE_AA);
  cv::putText(img, text, cv::Point(10, 24), cv::FONT_HERSHEY_SIMPLEX, 0.6,
              cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
}

nlohmann::json rows3(const Eigen::VectorXd& v, int n) {
  nlohmann::json a = nlohmann::json::array();
  for (int i = 0; i < n; ++i) a.push_back({v[3 * i], v[3 * i + 1], v[3 * i + 2]});
  return a;
}

struct Args {
  std::string input, init, out, overlay, model = "beam", truth;
  int stride = 1, first = 0, count = -1;
  bool quiet = false;
  bool compare_snake = false;
  bool verbose = false;
  bool stabilise = false;
  int forces_since = -1;  // frame index, or −1
};

// RMS distance (pixels) between a tracker's nodes and the truth nodes.
double node_rms_error(const rt::Tracker& tracker, const Eigen::MatrixXd& truth_nodes) {
  double sum = 0.0;
  const int n = tracker.num_nodes();
  for (int i = 0; i < n; ++i) {
    sum += (tracker.node_position(i) - truth_nodes.row(i).head<2>().transpose()).squaredNorm();
  }
  return std::sqrt(sum / n);
}

// The init polyline must lie on the first processed frame.
void check_init_on_frame(const tools::TrackInit& init, const std::string& init_path,
                         const cv::Mat& grey) {
  const int n = static_cast<int>(init.beam.rest_positions.cols());
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2d X = init.beam.rest_positions.col(i);
    if (X.x() < 0 || X.y() < 0 || X.x() > grey.cols - 1 || X.y() > grey.rows - 1) {
      throw tools::InputError(init_path + ": nodes[" + std::to_string(i) + "] = [" +
                              std::to_string(X.x()) + ", " + std::to_string(X.y()) +
                              "] is outside the first frame (" + std::to_string(grey.cols) + "x" +
                              std::to_string(grey.rows) + ")");
    }
  }
}

// What a run measured, for its summary.
struct TrackFigures {
  std::map<std::string, int> statuses, snake_statuses;
  std::vector<double> latencies, errors, load_errors, large_load_errors, stabilise_ms;
  std::vector<double> snake_errors, snake_latencies;
};

// The run's figures on the terminal: statuses, latency, stabilisation, errors against the truth,
// the snake baseline's, and the files written.
void print_track_summary(const Args& args, int processed, const std::string& source,
                         const tools::TrackInit& init, const rt::TrackerOptions& snake_options,
                         TrackFigures& figures) {
  std::map<std::string, int>& statuses = figures.statuses;
  std::map<std::string, int>& snake_statuses = figures.snake_statuses;
  std::vector<double>& latencies = figures.latencies;
  std::vector<double>& errors = figures.errors;
  std::vector<double>& load_errors = figures.load_errors;
  std::vector<double>& large_load_errors = figures.large_load_errors;
  std::vector<double>& stabilise_ms = figures.stabilise_ms;
  std::vector<double>& snake_errors = figures.snake_errors;
  std::vector<double>& snake_latencies = figures.snake_latencies;
  std::cout << "sinew-track: " << processed << " frames from " << source << " ("
            << (init.options.model == rt::TrackerModel::kBeam ? "beam" : "snake") << " model)\n";
  std::cout << "  status:";
  for (const auto& [k, v] : statuses) std::cout << " " << k << " " << v;
  std::cout << "\n  latency per frame: median " << tools::percentile(latencies, 0.5) << " us, p99 "
            << tools::percentile(latencies, 0.99) << " us\n";
  if (!stabilise_ms.empty()) {
    std::cout << "  stabilisation (ECC homography + warp, outside the tracker): median "
              << tools::percentile(stabilise_ms, 0.5) << " ms, p99 "
              << tools::percentile(stabilise_ms, 0.99) << " ms\n";
  }
  if (!errors.empty()) {
    double mean = 0.0;
    for (double e : errors) mean += e;
    std::cout << "  node RMS error vs truth: mean " << mean / errors.size() << " px, max "
              << *std::max_element(errors.begin(), errors.end()) << " px\n";
  }
  if (args.compare_snake) {
    std::cout << "  snake baseline (seed 000 §5.2, stretch " << snake_options.snake_stretch_weight
              << ", bend " << snake_options.snake_bend_weight << "):";
    for (const auto& [k, v] : snake_statuses) std::cout << " " << k << " " << v;
    std::cout << ", median latency " << tools::percentile(snake_latencies, 0.5) << " us";
    if (!snake_errors.empty()) {
      double mean = 0.0;
      for (double e : snake_errors) mean += e;
      std::cout << ", node RMS error mean " << mean / snake_errors.size() << " px, max "
                << *std::max_element(snake_errors.begin(), snake_errors.end()) << " px";
    }
    std::cout << "\n";
  }
  if (!load_errors.empty()) {
    std::cout << "  fitted load error vs truth: median "
              << tools::percentile(load_errors, 0.5) * 100 << " %, max "
              << *std::max_element(load_errors.begin(), load_errors.end()) * 100
              << " % (relative errors of tiny loads are large)";
    if (!large_load_errors.empty()) {
      std::cout << "; frames with lambda >= 1: max "
                << *std::max_element(large_load_errors.begin(), large_load_errors.end()) * 100
                << " %";
    }
    std::cout << "\n";
  }
  std::cout << "  results: " << args.out << "\n";
  if (!args.overlay.empty()) std::cout << "  overlay: " << args.overlay << "\n";
}

// The errors of a frame against the truth (sinew-synth's truth.jsonl): node RMS (and the
// snake's), and the fitted load's relative error at the load nodes; into the JSON line and the
// figures.
void compare_with_truth(const TruthFrame& truth_frame, const rt::Tracker& tracker,
                        const rt::Tracker& snake, const tools::TrackInit& init, bool compare_snake,
                        nlohmann::json& line, TrackFigures& figures) {
  const TruthFrame* const truth = &truth_frame;
  std::vector<double>& errors = figures.errors;
  std::vector<double>& snake_errors = figures.snake_errors;
  std::vector<double>& load_errors = figures.load_errors;
  std::vector<double>& large_load_errors = figures.large_load_errors;
  const double err = node_rms_error(tracker, truth->nodes);
  line["error_px"] = err;
  errors.push_back(err);
  if (compare_snake) {
    const double snake_err = node_rms_error(snake, truth->nodes);
    line["snake"]["error_px"] = snake_err;
    snake_errors.push_back(snake_err);
  }
  if (!init.load_nodes.empty() && init.options.model == rt::TrackerModel::kBeam) {
    Eigen::Vector2d applied = Eigen::Vector2d::Zero(), fitted = Eigen::Vector2d::Zero();
    for (int node : init.load_nodes) {
      applied += truth->loads.row(node).head<2>().transpose();
      fitted += tracker.fitted_loads().segment<2>(3 * node);
    }
    if (applied.norm() > 0) {
      const double rel = (fitted - applied).norm() / applied.norm();
      line["load_error"] = rel;
      load_errors.push_back(rel);
      if (truth->lambda >= 1.0) large_load_errors.push_back(rel);
    }
  }
}

// --verbose: one line per frame with its status, latency and errors against the truth.
void print_frame_line(int index, const rt::FrameSummary& s, const nlohmann::json& line,
                      bool compare_snake, const rt::FrameSummary& snake_summary) {
  std::printf("frame %4d  %-13s latency %6.0f us", index, rt::to_string(s.status), s.seconds * 1e6);
  if (line.contains("error_px"))
    std::printf("  node error %.3f px", line["error_px"].get<double>());
  if (line.contains("load_error")) {
    std::printf("  tip load error %5.1f %%", 100 * line["load_error"].get<double>());
  }
  if (compare_snake && line["snake"].contains("error_px")) {
    std::printf("  | snake %-13s node error %.2f px", rt::to_string(snake_summary.status),
                line["snake"]["error_px"].get<double>());
  }
  std::printf("\n");
}

int run(const Args& args) {
  tools::TrackInit init = tools::read_track_init(args.init);
  if (args.model == "snake") init.options.model = rt::TrackerModel::kSnake;
  const std::map<int, TruthFrame> truth =
      args.truth.empty() ? std::map<int, TruthFrame>{} : read_truth(args.truth);
  tools::FrameSource source(args.input, args.first, args.stride, args.count);

  rt::Tracker tracker(
      init.beam, init.options,
      init.options.model == rt::TrackerModel::kBeam ? init.load_nodes : std::vector<int>{});
  if (!tracker.valid()) throw tools::InputError(args.init + ": " + tracker.error());
  // The seed's comparison (§5.2): the snake-like baseline on the same frames, same image term.
  rt::TrackerOptions snake_options = init.options;
  snake_options.model = rt::TrackerModel::kSnake;
  rt::Tracker snake(init.beam, snake_options);
  TrackFigures figures;
  std::vector<double>& snake_latencies = figures.snake_latencies;
  std::map<std::string, int>& snake_statuses = figures.snake_statuses;
  const int n = tracker.num_nodes();

  std::ofstream out(args.out + ".tmp");
  if (!out) throw tools::InputError(args.out + ": cannot open file for writing");
  tools::OverlaySink overlay(args.overlay);

  std::vector<double>& latencies = figures.latencies;
  std::vector<double>& stabilise_ms = figures.stabilise_ms;
  Eigen::VectorXd forces_at_since;  // the reported forces on frame --forces-since
  std::optional<rt::Stabiliser> stabiliser;
  cv::Mat stabilised;
  Eigen::Matrix2Xd polyline(2, n);
  std::map<std::string, int>& statuses = figures.statuses;
  cv::Mat grey, colour;
  int index = 0, processed = 0;
  while (source.next(grey, index)) {
    if (processed == 0) check_init_on_frame(init, args.init, grey);
    nlohmann::json homography;
    if (args.stabilise) {
      // Every frame is resampled into the first processed frame's coordinates (seed 000 §5.2).
      if (!stabiliser) stabiliser.emplace(grey);
      for (int i = 0; i < n; ++i) polyline.col(i) = tracker.node_position(i);
      const rt::StabiliserSummary st = stabiliser->stabilise(grey, polyline, stabilised);
      stabilise_ms.push_back(st.seconds * 1e3);
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) homography.push_back(st.homography(r, c));
      }
      grey = stabilised;
    }
    const rt::ImageView view{grey.ptr<std::uint8_t>(), grey.cols, grey.rows,
                             static_cast<std::ptrdiff_t>(grey.step[0])};
    const rt::FrameSummary s = tracker.track(view);
    rt::FrameSummary snake_summary;
    if (args.compare_snake) {
      snake_summary = snake.track(view);
      snake_latencies.push_back(snake_summary.seconds * 1e6);
      ++snake_statuses[rt::to_string(snake_summary.status)];
    }
    latencies.push_back(s.seconds * 1e6);
    ++statuses[rt::to_string(s.status)];

    nlohmann::json line;
    line["frame"] = index;
    line["status"] = rt::to_string(s.status);
    nlohmann::json nodes = nlohmann::json::array();
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector2d x = tracker.node_position(i);
      nodes.push_back({x.x(), x.y(), tracker.state()[3 * i + 2]});
    }
    line["nodes"] = nodes;
    line["forces"] = rows3(init.load_nodes.empty() || init.options.model == rt::TrackerModel::kSnake
                               ? tracker.forces()
                               : tracker.fitted_loads(),
                           n);
    if (!init.load_nodes.empty()) line["node_forces"] = rows3(tracker.forces(), n);
    if (args.forces_since >= 0 && index >= args.forces_since) {
      // Loads between two chosen frames (seed 000 §4): both are measured from the first frame's
      // shape, so the load that takes the beam from frame A's shape to this one is their
      // difference.
      const Eigen::VectorXd& now =
          init.load_nodes.empty() ? tracker.forces() : tracker.fitted_loads();
      if (forces_at_since.size() == 0) forces_at_since = now;
      line["forces_since"] = rows3(now - forces_at_since, n);
      line["forces_since_frame"] = args.forces_since;
    }
    line["rms_px"] = s.rms_px;
    line["verify_px"] = s.verified ? nlohmann::json(s.verify_px) : nlohmann::json(nullptr);
    line["iterations"] = s.iterations;
    line["repetitions"] = s.repetitions;
    line["inlier_fraction"] = s.inlier_fraction;
    line["object_fraction"] = s.object_fraction;
    line["latency_us"] = s.seconds * 1e6;
    if (args.stabilise) {
      line["homography"] = homography;  // reference-frame pixels → this frame's pixels
      line["stabilise_ms"] = stabilise_ms.back();
    }
    if (!init.load_nodes.empty()) {
      line["load_fit_rms_px"] = s.load_fit_rms_px;
      line["loads_fitted"] = s.loads_fitted;
    }

    if (args.compare_snake) {
      nlohmann::json snake_nodes = nlohmann::json::array();
      for (int i = 0; i < n; ++i) {
        const Eigen::Vector2d x = snake.node_position(i);
        snake_nodes.push_back({x.x(), x.y()});
      }
      line["snake"] = {{"status", rt::to_string(snake_summary.status)},
                       {"nodes", snake_nodes},
                       {"rms_px", snake_summary.rms_px},
                       {"latency_us", snake_summary.seconds * 1e6}};
    }
    const auto t = truth.find(index);
    if (t != truth.end() && t->second.nodes.rows() == n) {
      compare_with_truth(t->second, tracker, snake, init, args.compare_snake, line, figures);
    }
    out << line.dump() << "\n";
    if (args.verbose) print_frame_line(index, s, line, args.compare_snake, snake_summary);

    if (overlay.enabled()) {
      cv::cvtColor(grey, colour, cv::COLOR_GRAY2BGR);
      draw_overlay(colour, tracker, s, index);
      overlay.write(colour, index);
    }
    ++processed;
    if (!args.quiet && processed % 50 == 0) {
      std::cerr << "sinew-track: " << processed << " frames, last " << rt::to_string(s.status)
                << ", median latency " << tools::percentile(latencies, 0.5) << " us\n";
    }
  }
  out.close();
  if (processed == 0) {
    std::filesystem::remove(args.out + ".tmp");
    throw tools::InputError(args.input + ": no frame to process (check --first/--count)");
  }
  std::filesystem::rename(args.out + ".tmp", args.out);

  if (!args.quiet) {
    print_track_summary(args, processed, source.description(), init, snake_options, figures);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Track a beam-like object through frames and recover its forces (Sinew)"};
  Args args;
  app.add_option("--input", args.input, "video file, image, folder of images or printf pattern");
  app.add_option("--init", args.init, "init.json: polyline on the first frame, material, ...");
  bool whiskers = false;
  std::string face = "auto";
  double min_length = 40.0;
  bool repair_traces = false;
  double associate_home_px = 0.0;
  double held_ridge_px = sinew::rt::WhiskerTrackerOptions{}.held_ridge_px;
  double associate_contrast_ratio = sinew::rt::WhiskerTrackerOptions{}.associate_contrast_ratio;
  double start_clearance_px = 0.0;
  double start_mean_surround_px = 0.0;
  bool profile_position = false;
  bool fit_follicle_position = false;
  std::string redetect = "every";
  sinew::rt::WhiskerReadoutOptions readout;
  std::vector<double> curvature_window;
  std::string csv;
  app.add_flag("--whiskers", whiskers,
               "find every whisker leaving the face on the first frame and track them all "
               "(no --init)");
  app.add_option("--face", face, "--whiskers: the border the face touches")
      ->check(CLI::IsMember({"auto", "left", "right", "top", "bottom"}));
  app.add_option("--min-length-px", min_length, "--whiskers: shortest whisker reported")
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--repair-traces", repair_traces,
               "--whiskers: cut traces that hop between converging whiskers and extend them to "
               "the face (finds more whiskers in a dense pad; see docs/tracker.md)");
  app.add_option("--associate-home-px", associate_home_px,
                 "--whiskers: keep identities from walking along a dense pad: a detection also "
                 "costs by its distance from the whisker's first follicle (moved with the head); "
                 "15 holds the shared video's identities but tracks fewer whisker-frames on a "
                 "ridge (docs/tracker.md); 0 (default) off")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--held-ridge-px", held_ridge_px,
                 "--whiskers: whiskers are fitted brightest first and each one's search leaves out "
                 "the candidates this near the whiskers fitted before it (a faint whisker beside a "
                 "bright one keeps its own ridge); 0 off")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app.add_option("--associate-contrast-ratio", associate_contrast_ratio,
                 "--whiskers: a whisker's darkness is its own: a detection whose ridge contrast "
                 "differs from the whisker's by this factor costs as much as one 10 px away, so a "
                 "faint whisker's identity does not walk onto a darker neighbour; 0 off")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app.add_option("--start-clearance-px", start_clearance_px,
                 "--whiskers: no search line across a whisker within this distance of its "
                 "follicle; 6 removes the follicle angle's lag on rendered whisking (0.89 -> 1.006 "
                 "of the true angle) but holds the shared video's follicles worse "
                 "(docs/tracker.md); 0 (default) off")
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--profile-position", profile_position,
               "--whiskers: each search line's sub-pixel position from the profile's darkness, "
               "not the ridge response (less noise: rendered curve 0.098 -> 0.063 px); with "
               "--start-mean-surround-px 6 --fit-follicle-position --rest-frames 20 the rendered "
               "contact moments' error falls (docs/tracker.md); off by default");
  app.add_option("--start-mean-surround-px", start_mean_surround_px,
                 "--whiskers: within this distance of its follicle a whisker's ridge depth is "
                 "taken below both sides' mean, not the darker side (the face's curved edge moves "
                 "the latter sideways); 6 takes the rendered contact moment's error from 17-25 to "
                 "10-14 %, but three whisker safety tests fail with it (docs/tracker.md); "
                 "0 (default) off")
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--fit-follicle-position", fit_follicle_position,
               "--whiskers: the contact load fit also fits the follicle's position (the tracked "
               "one lies 0.2-0.4 px sideways under a large load): sliding pole 19.5 -> 9.2 % "
               "moment error, but the still pad's small loads 10.7 -> 14.0 % (docs/tracker.md)");
  app.add_option("--redetect", redetect,
                 "--whiskers: detect again after tracking on every frame (default; cameras "
                 "below ~200 fps, whose whiskers move further than the search reaches), only on "
                 "frames with a lost whisker (high-speed cameras), or never")
      ->check(CLI::IsMember({"every", "lost", "never"}));
  app.add_option("--mm-per-px", readout.physics.mm_per_px,
                 "--whiskers: image scale; with it moments, forces and curvatures are in SI "
                 "units (needs --base-radius-um)")
      ->check(CLI::NonNegativeNumber);
  std::string whisker_preset;
  app.add_option("--whisker-preset", whisker_preset,
                 "--whiskers: a whisker's modulus, radii and length from the literature: rat-c2, "
                 "or mouse-c2 (its modulus borrowed from the rat: none is measured in mice); "
                 "sources in docs/tracker.md; the options below override single values")
      ->check(CLI::IsMember(rt::whisker_preset_names()));
  app.add_option("--young-modulus-gpa", readout.physics.young_modulus_gpa,
                 "--whiskers: Young's modulus (default 3.34, rat vibrissae, Quist et al. 2011)");
  app.add_option("--base-radius-um", readout.physics.base_radius_um,
                 "--whiskers: whisker radius at the follicle, micrometres");
  app.add_option("--tip-radius-um", readout.physics.tip_radius_um,
                 "--whiskers: whisker radius at the tip, micrometres (default 0)");
  app.add_option("--whisker-length-mm", readout.physics.length_mm,
                 "--whiskers: full whisker length for the taper (default: measured per whisker "
                 "from its darkness along it on the first frame, else the tracked length)");
  app.add_option("--axis-angle-deg", readout.axis_angle_deg,
                 "--whiskers: the head axis in the image, degrees from +x towards +y; base "
                 "angles are measured from it");
  app.add_option("--curvature-window", curvature_window,
                 "--whiskers: arc-length window from the follicle for the curvature, pixels "
                 "(two numbers, default 0 30)")
      ->expected(2);
  app.add_option("--moment-elements", readout.moment_elements,
                 "--whiskers: M0 from this many elements from the follicle (default 3)")
      ->check(CLI::PositiveNumber);
  int rest_frame = 0;
  app.add_option("--rest-frame", rest_frame,
                 "--whiskers: the frame (counted from the first processed) whose fits are the "
                 "whiskers at rest; choose one where nothing touches them (default 0)")
      ->check(CLI::NonNegativeNumber);
  int rest_frames = 1;
  app.add_option("--rest-frames", rest_frames,
                 "--whiskers: the rest shape is the mean of this many frames without contact "
                 "from the rest frame on, each turned about its follicle onto the first "
                 "(default 1)")
      ->check(CLI::PositiveNumber);
  app.add_option("--csv", csv, "--whiskers: also write one row per whisker per frame (CSV)");
  std::string plots, hdf5;
  app.add_option("--hdf5", hdf5,
                 "--whiskers: also write the table and the full centrelines (HDF5, for h5py and "
                 "pandas)");
  app.add_option("--plots", plots,
                 "--whiskers: folder for per-whisker time series (base angle, curvature change, "
                 "moment at the follicle; PNG)");
  std::string detection_picture;
  app.add_option("--detection-picture", detection_picture,
                 "--whiskers: PNG of the first frame's detection, magnified 3x: the whiskers found "
                 "and every trace that was not, coloured by the reason (why a whisker was missed)");
  app.add_option("--out", args.out, "results, one JSON object per frame (JSON Lines)");
  std::string batch;
  tools::TrackBatchOptions batch_options;
  std::optional<long> batch_task;
  app.add_option("--batch", batch,
                 "whisker videos from a manifest (JSON: videos with their face side, scale and "
                 "physics, or a folder and a glob), one results folder each and a summary table; "
                 "videos already done are skipped (docs/whisker_batch.md)");
  app.add_option("--jobs", batch_options.jobs, "--batch: videos tracked at once (processes)")
      ->check(CLI::PositiveNumber);
  app.add_option("--task", batch_task,
                 "--batch: track video N (0-based) alone; default: SLURM_ARRAY_TASK_ID when set")
      ->check(CLI::NonNegativeNumber);
  bool batch_list = false;
  app.add_flag("--list", batch_list,
               "--batch: print the manifest's videos, one line each (index, video, results "
               "folder), and track nothing: `--list | wc -l` sizes a Slurm job array");
  app.add_flag("--gather", batch_options.gather,
               "--batch: track nothing; the summary table from the videos' results (after a "
               "Slurm job array)");
  app.add_option("--overlay", args.overlay, "folder for overlay PNGs, or a .mp4/.avi file");
  app.add_option("--stride", args.stride, "process every K-th frame")->check(CLI::PositiveNumber);
  app.add_option("--first", args.first, "index of the first frame to process")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--count", args.count, "number of frames to process (default: all)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--model", args.model, "beam (default) or snake (the seed's baseline)")
      ->check(CLI::IsMember({"beam", "snake"}));
  app.add_option("--truth", args.truth, "truth.jsonl from sinew-synth: report errors against it");
  app.add_flag("--quiet", args.quiet, "print nothing but errors");
  app.add_option("--forces-since", args.forces_since,
                 "also report the loads between frame N and each later frame (forces_since)")
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--stabilise", args.stabilise,
               "moving camera: map every frame into the first frame's coordinates (homography)");
  app.add_flag("--verbose", args.verbose, "print one line per frame (errors against --truth)");
  app.add_flag("--compare-snake", args.compare_snake,
               "also run the snake baseline on the same frames and report both");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  try {
    if (!batch.empty()) {
      if (!args.input.empty() || !args.out.empty()) {
        throw tools::InputError(
            "--batch takes the videos and folders from the manifest; drop "
            "--input and --out");
      }
      const tools::TrackBatchManifest manifest = tools::read_track_batch_manifest(batch);
      if (batch_list) {
        for (std::size_t i = 0; i < manifest.videos.size(); ++i) {
          std::cout << i << "\t" << manifest.videos[i].video << "\t" << manifest.videos[i].out_dir
                    << "\n";
        }
        return 0;
      }
      batch_options.quiet = args.quiet;
      batch_options.task = tools::select_array_task(manifest.videos.size(), manifest.path, "video",
                                                    batch_task, std::getenv("SLURM_ARRAY_TASK_ID"));
      return tools::run_track_batch(manifest, batch_options);
    }
    if (args.input.empty()) throw tools::InputError("--input is required (or --batch)");
    if (args.out.empty()) throw tools::InputError("--out is required");
    if (whiskers) {
      if (!args.init.empty()) throw tools::InputError("--whiskers finds the whiskers; drop --init");
      tools::WhiskerTrackArgs w;
      w.input = args.input;
      w.out = args.out;
      w.overlay = args.overlay;
      w.face = face;
      w.first = args.first;
      w.stride = args.stride;
      w.count = args.count;
      w.quiet = args.quiet;
      w.min_length_px = min_length;
      w.repair_traces = repair_traces;
      w.associate_home_px = associate_home_px;
      w.held_ridge_px = held_ridge_px;
      w.associate_contrast_ratio = associate_contrast_ratio;
      w.start_clearance_px = start_clearance_px;
      w.start_mean_surround_px = start_mean_surround_px;
      w.profile_position = profile_position;
      w.fit_follicle_position = fit_follicle_position;
      w.redetect = redetect;
      w.rest_frame = rest_frame;
      w.rest_frames = rest_frames;
      if (!whisker_preset.empty()) {
        // The preset, then every value given on the command line over it.
        const rt::WhiskerPhysics given = readout.physics;
        readout.physics = *rt::whisker_preset(whisker_preset);
        readout.physics.mm_per_px = given.mm_per_px;
        if (app.count("--young-modulus-gpa"))
          readout.physics.young_modulus_gpa = given.young_modulus_gpa;
        if (app.count("--base-radius-um")) readout.physics.base_radius_um = given.base_radius_um;
        if (app.count("--tip-radius-um")) readout.physics.tip_radius_um = given.tip_radius_um;
        if (app.count("--whisker-length-mm")) readout.physics.length_mm = given.length_mm;
      }
      if (!curvature_window.empty()) {
        readout.curvature_from_px = curvature_window[0];
        readout.curvature_to_px = curvature_window[1];
      }
      w.readout = readout;
      w.csv = csv;
      w.plots = plots;
      w.hdf5 = hdf5;
      w.detection_picture = detection_picture;
      return tools::run_whiskers(w);
    }
    if (args.init.empty()) throw tools::InputError("--init is required (or --whiskers)");
    return run(args);
  } catch (const std::exception& e) {
    std::cerr << "sinew-track: " << e.what() << "\n";
    return 2;
  }
}
