// sinew-synth: synthetic image sequences of a plane beam under known loads, simulated with Sinew's
// own StaticBeamSolver, for end-to-end tests of the tracker.
//   sinew-synth --scenario cantilever|free_curved|whisker-pad --out DIR [--frames 40] [--width
//   1024]
//     [--height 768] [--elements 16] [--thickness thick|thin] [--half-width-px 6] [--lambda-max 5]
//     [--noise 8] [--clutter 12] [--occluder FIRST:COUNT] [--vanish FIRST:COUNT]
//     [--camera-motion none|pan_rotate] [--seed 1]
//
// Writes
//   DIR/frames/f_0000.png ...  8-bit grey frames (old f_NNNN.png files there are removed first)
//   DIR/init.json              the tracker's input:
//     {"nodes": [[x, y], ...]        tracker nodes on the first frame (its reference), pixels,
//      "fixed": [{"node": 0, "dofs": ["ux", "uy", "theta"]}]   cantilever; [] for free_curved,
//      "material": {"E", "G", "A", "I"}   pixel units: section height h = 2·half_width, depth 1,
//                                         E = 1000, G = E/2.6, A = h, I = h³/12,
//      "observation": "edge" (thick) | "dark_line" (thin), "half_width_px": w,
//      "load_nodes": [n]              cantilever only: the loaded (tip) node}
//   DIR/truth.jsonl            one JSON object per frame and line:
//     {"frame": k,
//      "nodes": [[x, y, theta], ...]   true state at the tracker's nodes (fine node 4i of the
//                                      simulation) in REFERENCE-FRAME pixels (frame 0's camera,
//                                      even with camera motion); theta = cross-section rotation
//                                      relative to frame 0, rad, positive from +x towards +y,
//      "loads": [[fx, fy, m], ...]     applied loads at the tracker's nodes, reference-frame axes
//                                      (zeros except loaded nodes; free_curved: the three forces,
//                                      balanced in the deformed state, turned with the rigid
//                                      motion),
//      "lambda": P·L²/EI               (P: tip load, or free_curved's middle force; L: length),
//      "occluded": bool, "visible": bool (false on --vanish frames),
//      "homography": [9 numbers]       row-major H with H(2,2) = 1 mapping reference-frame pixels
//                                      to this frame's pixels (identity without camera motion)}
//   Pixel centres are at integer coordinates; (0, 0) is the centre of the top-left pixel.
//
// Scenarios (L = 0.6·width; the simulation mesh has 4 elements per tracker element):
//   cantilever   straight, clamped at node 0 at (0.2·width, 0.3·height), tilted 3° up; dead tip
//                load normal to the reference axis (towards +y), λ = lambda_max·k/(frames − 1);
//                each frame warm-started from the previous one.
//   free_curved  whisker-like 60° curve (curvature falling linearly from base to tip, slightly
//                reversed near the tip), tracker element lengths falling 2:1 from base to tip, no
//                boundary condition for the tracker; three parallel forces normal to the chord
//                (middle one P outwards, end ones balancing force and moment in the deformed
//                state), λ = lambda_max·sin(0.75π·k/(frames − 1)); the solver clamps node 0 only to
//                remove rigid motion, then a slow rigid motion (≤ 0.5°/frame, ≤ 2 px/frame) moves
//                the whole beam.
// Exit status: 0 written; 1 the simulation failed (solver did not converge); 2 bad arguments or
// unwritable output (one line on stderr naming the option).
#include <CLI/CLI.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <regex>
#include <sstream>

#include "tools/io/json_file.hpp"
#include "tools/synth/renderer.hpp"
#include "tools/synth/scenario.hpp"
#include "tools/synth/whisker_pad.hpp"

namespace {

namespace fs = std::filesystem;
using namespace sinew;
using namespace sinew::tools::synth;

/// A bad argument: what() is the one-line message, starting with the option.
using UsageError = tools::InputError;

/// Parses FIRST:COUNT for `option` (FIRST ≥ 0, COUNT ≥ 1, within the frames).
FrameRange parse_frame_range(const std::string& option, const std::string& text, int frames) {
  static const std::regex pattern(R"(\s*(\d{1,9})\s*:\s*(\d{1,9})\s*)");
  std::smatch m;
  if (!std::regex_match(text, m, pattern)) {
    throw UsageError(option + " " + text + ": expected FIRST:COUNT (two non-negative integers)");
  }
  FrameRange r;
  r.first = std::stoi(m[1]);
  r.count = std::stoi(m[2]);
  if (r.count < 1) throw UsageError(option + " " + text + ": COUNT must be at least 1");
  if (r.first + static_cast<long>(r.count) > frames) {
    throw UsageError(option + " " + text + ": frames " + std::to_string(r.first) + ".." +
                     std::to_string(r.first + static_cast<long>(r.count) - 1) +
                     " are not all within the " + std::to_string(frames) + " frames (0.." +
                     std::to_string(frames - 1) + ")");
  }
  return r;
}

template <typename T>
void require_range(const std::string& option, T value, T low, T high) {
  if (!(value >= low && value <= high)) {
    std::ostringstream s;
    s << option << " " << value << ": must be in [" << low << ", " << high << "]";
    throw UsageError(s.str());
  }
}

std::string frame_name(int k) {
  std::ostringstream s;
  s << "f_" << std::setw(4) << std::setfill('0') << k << ".png";
  return s.str();
}

nlohmann::json init_json(const SynthOptions& o, const Simulation& sim) {
  nlohmann::json init;
  init["nodes"] = nlohmann::json::array();
  for (Eigen::Index k = 0; k < sim.beam.rest_positions.cols(); ++k) {
    init["nodes"].push_back({sim.beam.rest_positions(0, k), sim.beam.rest_positions(1, k)});
  }
  init["fixed"] = nlohmann::json::array();
  if (sim.beam.clamped_base)
    init["fixed"].push_back({{"node", 0}, {"dofs", {"ux", "uy", "theta"}}});
  const common::BeamMaterial& m = sim.beam.material;
  init["material"] = {{"E", m.E}, {"G", m.G}, {"A", m.A}, {"I", m.I}};
  init["observation"] = o.thickness == Thickness::kThick ? "edge" : "dark_line";
  init["half_width_px"] = o.half_width_px;
  if (!sim.beam.load_nodes.empty()) init["load_nodes"] = sim.beam.load_nodes;
  return init;
}

nlohmann::json truth_json(const SynthOptions& o, const FrameTruth& t, int k) {
  nlohmann::json line;
  line["frame"] = k;
  line["nodes"] = nlohmann::json::array();
  line["loads"] = nlohmann::json::array();
  for (Eigen::Index i = 0; i < t.nodes.cols(); ++i) {
    line["nodes"].push_back({t.nodes(0, i), t.nodes(1, i), t.nodes(2, i)});
    line["loads"].push_back({t.loads(0, i), t.loads(1, i), t.loads(2, i)});
  }
  line["lambda"] = t.lambda;
  line["occluded"] = o.occluder.has_value() && o.occluder->contains(k);
  line["visible"] = !(o.vanish.has_value() && o.vanish->contains(k));
  const Eigen::Matrix3d H = camera_homography(o, k);
  line["homography"] = nlohmann::json::array();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) line["homography"].push_back(H(r, c));
  }
  return line;
}

/// Writes the lines atomically (temporary file + rename), like write_json_file.
void write_jsonl_file(const std::string& path, const std::vector<nlohmann::json>& lines) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw UsageError("--out: " + path + ": cannot open file for writing");
    for (const auto& line : lines) out << line.dump() << "\n";
    out.flush();
    if (!out) throw UsageError("--out: " + path + ": write failed");
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    throw UsageError("--out: " + path + ": cannot move the finished file into place");
  }
}

/// Creates DIR/frames and removes frames of an earlier run (f_NNNN.png only).
fs::path prepare_output(const std::string& out) {
  const fs::path frames = fs::path(out) / "frames";
  std::error_code ec;
  fs::create_directories(frames, ec);
  if (ec || !fs::is_directory(frames)) {
    throw UsageError("--out " + out + ": cannot create " + frames.string() + ": " +
                     (ec ? ec.message() : "not a directory"));
  }
  static const std::regex frame_file(R"(f_\d+\.png)");
  for (const auto& entry : fs::directory_iterator(frames, ec)) {
    if (entry.is_regular_file() && std::regex_match(entry.path().filename().string(), frame_file)) {
      fs::remove(entry.path(), ec);
    }
  }
  return frames;
}

int run(const SynthOptions& o, const std::string& out) {
  const Simulation sim = simulate(o);
  if (auto err = check_beam_inside_image(o, sim)) throw UsageError(*err);

  const fs::path frames_dir = prepare_output(out);
  Renderer renderer(o, sim);
  std::vector<nlohmann::json> truth;
  for (int k = 0; k < o.frames; ++k) {
    const cv::Mat image = renderer.render(k);
    const fs::path file = frames_dir / frame_name(k);
    bool written = false;
    try {
      written = cv::imwrite(file.string(), image);
    } catch (const cv::Exception&) {
      written = false;
    }
    if (!written) throw UsageError("--out " + out + ": cannot write " + file.string());
    truth.push_back(truth_json(o, sim.frames[k], k));
    if ((k + 1) % 10 == 0 || k + 1 == o.frames) {
      const FrameTruth& t = sim.frames[k];
      const Eigen::Index tip = t.nodes.cols() - 1;
      std::cout << "frame " << k + 1 << "/" << o.frames << ": lambda " << t.lambda << ", tip ("
                << t.nodes(0, tip) << ", " << t.nodes(1, tip) << "), " << t.solver_iterations
                << " Newton iterations\n"
                << std::flush;
    }
  }
  const std::string truth_path = (fs::path(out) / "truth.jsonl").string();
  const std::string init_path = (fs::path(out) / "init.json").string();
  write_jsonl_file(truth_path, truth);
  try {
    tools::write_json_file(init_path, init_json(o, sim));
  } catch (const tools::InputError& e) {
    throw UsageError(std::string("--out: ") + e.what());
  }
  std::cout << "wrote " << o.frames << " frames " << (frames_dir / frame_name(0)).string() << " .. "
            << frame_name(o.frames - 1) << ", " << init_path << ", " << truth_path << "\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Synthetic image sequences of a plane beam under known loads (Sinew)"};
  std::string scenario, out, thickness = "thick", camera = "none", occluder, vanish;
  SynthOptions o;
  double half_width = 0.0;
  app.add_option("--scenario", scenario, "cantilever | free_curved | whisker-pad")->required();
  WhiskerPadOptions pad;
  std::string face_motion = "none";
  bool no_pole = false, no_lick_port = false;
  app.add_option("--whiskers", pad.whiskers, "whisker-pad: number of whiskers")
      ->capture_default_str();
  app.add_option("--contrast-min", pad.contrast_min,
                 "whisker-pad: base contrast of the faintest whisker, grey levels")
      ->capture_default_str();
  app.add_option("--contrast-max", pad.contrast_max,
                 "whisker-pad: base contrast of the darkest whisker, grey levels")
      ->capture_default_str();
  app.add_option("--face-motion", face_motion, "whisker-pad: none | translate_rotate")
      ->capture_default_str();
  app.add_option("--fps", pad.fps, "whisker-pad: camera frame rate")->capture_default_str();
  app.add_option("--whisk-hz", pad.whisk_hz, "whisker-pad: whisking frequency")
      ->capture_default_str();
  app.add_flag("--no-pole", no_pole, "whisker-pad: no pole");
  app.add_option(
         "--pole-travel", pad.pole_travel,
         "whisker-pad: the pole slides from 60 % of the pressed whisker's length towards its "
         "follicle by up to this fraction of the length and back: a moving contact point, "
         "[0, 0.3]")
      ->capture_default_str();
  app.add_flag("--no-lick-port", no_lick_port, "whisker-pad: no lick port");
  app.add_option("--out", out, "output folder (created): frames/, init.json, truth.jsonl")
      ->required();
  CLI::Option* frames_option =
      app.add_option("--frames", o.frames, "number of frames, >= 2 (whisker-pad: 200)")
          ->capture_default_str();
  CLI::Option* width_option =
      app.add_option("--width", o.width, "image width, pixels (whisker-pad: 640)")
          ->capture_default_str();
  CLI::Option* height_option =
      app.add_option("--height", o.height, "image height, pixels (whisker-pad: 480)")
          ->capture_default_str();
  app.add_option("--elements", o.elements, "tracker elements (the simulation uses 4x)")
      ->capture_default_str();
  app.add_option("--thickness", thickness, "thick (edges, half-width 6) | thin (dark line, 1.25)")
      ->capture_default_str();
  CLI::Option* half_width_option = app.add_option("--half-width-px", half_width,
                                                  "half-width of the drawn beam, pixels "
                                                  "(default 6 thick, 1.25 thin)");
  app.add_option("--lambda-max", o.lambda_max, "largest P L^2/EI of the sequence")
      ->capture_default_str();
  CLI::Option* noise_option =
      app.add_option("--noise", o.noise, "Gaussian noise sigma, grey levels (whisker-pad: 4)")
          ->capture_default_str();
  app.add_option("--clutter", o.clutter, "number of clutter line segments")->capture_default_str();
  app.add_option("--occluder", occluder,
                 "FIRST:COUNT frames with an occluder on the beam's middle");
  app.add_option("--vanish", vanish, "FIRST:COUNT frames without the beam");
  app.add_option("--camera-motion", camera, "none | pan_rotate")->capture_default_str();
  app.add_option("--seed", o.seed, "random seed")->capture_default_str();
  app.footer(
      "truth.jsonl nodes and loads are in the first frame's pixel coordinates; each line's "
      "homography maps them into that frame.");
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "sinew-synth: " << e.what() << "\n";
    return 2;
  }
  try {
    if (scenario == "whisker-pad") {
      if (frames_option->count()) pad.frames = o.frames;
      if (width_option->count()) pad.width = o.width;
      if (height_option->count()) pad.height = o.height;
      if (noise_option->count()) pad.noise = o.noise;
      pad.seed = o.seed;
      pad.pole = !no_pole;
      pad.lick_port = !no_lick_port;
      if (face_motion == "none") {
        pad.face_motion = false;
      } else if (face_motion == "translate_rotate") {
        pad.face_motion = true;
      } else {
        throw UsageError("--face-motion " + face_motion + ": must be none or translate_rotate");
      }
      require_range("--frames", pad.frames, 2, 100000);
      if (!(pad.pole_travel >= 0.0 && pad.pole_travel <= 0.3)) {
        throw UsageError("--pole-travel " + std::to_string(pad.pole_travel) +
                         ": must be in [0, 0.3]");
      }
      require_range("--width", pad.width, 320, 16384);
      require_range("--height", pad.height, 240, 16384);
      require_range("--whiskers", pad.whiskers, 1, 40);
      require_range("--noise", pad.noise, 0.0, 255.0);
      require_range("--contrast-min", pad.contrast_min, 0.0, 150.0);
      require_range("--contrast-max", pad.contrast_max, pad.contrast_min, 150.0);
      require_range("--fps", pad.fps, 1.0, 1e6);
      require_range("--whisk-hz", pad.whisk_hz, 0.0, 1000.0);
      write_whisker_pad(pad, out);
      std::cout << "wrote " << pad.frames << " frames of " << pad.whiskers << " whiskers to " << out
                << "/frames/, " << out << "/truth.jsonl\n";
      return 0;
    }
    if (scenario == "cantilever") {
      o.scenario = Scenario::kCantilever;
    } else if (scenario == "free_curved") {
      o.scenario = Scenario::kFreeCurved;
    } else {
      throw UsageError("--scenario " + scenario +
                       ": unknown scenario (cantilever, free_curved, whisker-pad)");
    }
    if (thickness == "thick") {
      o.thickness = Thickness::kThick;
    } else if (thickness == "thin") {
      o.thickness = Thickness::kThin;
    } else {
      throw UsageError("--thickness " + thickness + ": must be thick or thin");
    }
    if (camera == "none") {
      o.camera_motion = CameraMotion::kNone;
    } else if (camera == "pan_rotate") {
      o.camera_motion = CameraMotion::kPanRotate;
    } else {
      throw UsageError("--camera-motion " + camera + ": must be none or pan_rotate");
    }
    o.half_width_px = half_width_option->count() > 0
                          ? half_width
                          : (o.thickness == Thickness::kThick ? 6.0 : 1.25);
    require_range("--frames", o.frames, 2, 100000);
    require_range("--width", o.width, 32, 16384);
    require_range("--height", o.height, 32, 16384);
    require_range("--elements", o.elements, 2, 1000);
    require_range("--half-width-px", o.half_width_px, 0.5, 100.0);
    require_range("--lambda-max", o.lambda_max, 0.0, 1000.0);
    require_range("--noise", o.noise, 0.0, 255.0);
    require_range("--clutter", o.clutter, 0, 10000);
    if (!occluder.empty()) o.occluder = parse_frame_range("--occluder", occluder, o.frames);
    if (!vanish.empty()) o.vanish = parse_frame_range("--vanish", vanish, o.frames);
    return run(o, out);
  } catch (const tools::InputError& e) {
    std::cerr << "sinew-synth: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "sinew-synth: " << e.what() << "\n";
    return 1;
  }
}
