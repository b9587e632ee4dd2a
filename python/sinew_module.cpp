// The Python module `sinew` (pybind11): the tracker a lab drives from its own Python loop.
//   tracker = sinew.Tracker("init.json")          # or the same content as a dict
//   result = tracker.track(frame)                  # 2-D uint8 numpy array (a grey frame)
// The frame is read in place (no copy); tracking runs without the GIL and allocates nothing in C++.
// Errors raise ValueError with the one-line message sinew-track prints.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <memory>
#include <optional>
#include <string>

#include "rt/tracker.hpp"
#include "rt/whisker/readout.hpp"
#include "rt/whisker/session.hpp"
#include "tools/simulate/simulation.hpp"
#include "tools/track/track_init.hpp"
#ifdef SINEW_PYTHON_OFFLINE
#include <pybind11/eigen.h>

#include <chrono>
#include <cstdio>
#include <filesystem>

#include "common/timing.hpp"
#include "offline/registration/register_case.hpp"
#include "tools/io/json_file.hpp"
#include "tools/register/case_file.hpp"
#include "tools/register/outputs.hpp"
#endif

namespace py = pybind11;
using namespace sinew;

namespace {

// parse(document, name) on a JSON file (errors with the value's line and column) or a dict
// (named "<dict>").
template <class Parse>
auto parse_source(const py::object& source, const char* caller, Parse parse) {
  if (py::isinstance<py::str>(source)) {
    const std::string name = source.cast<std::string>();
    return tools::parse_json_file(name,
                                  [&](const nlohmann::json& doc) { return parse(doc, name); });
  }
  if (py::isinstance<py::dict>(source)) {
    const std::string text = py::module_::import("json").attr("dumps")(source).cast<std::string>();
    return parse(nlohmann::json::parse(text), std::string("<dict>"));
  }
  throw py::type_error(std::string(caller) + ": a path to a JSON file or a dict");
}

rt::FaceSide face_side(const std::string& face) {
  if (auto side = rt::face_side_from_string(face)) return *side;
  throw py::value_error("face = \"" + face + "\" must be auto, left, right, top or bottom");
}

rt::Redetect redetect_mode(const std::string& redetect) {
  if (auto mode = rt::redetect_from_string(redetect)) return *mode;
  throw py::value_error("redetect = \"" + redetect + "\" must be every, lost or never");
}

// A grey frame read in place: a C-contiguous 2-D uint8 array.
rt::ImageView grey_view(const py::array_t<std::uint8_t, py::array::c_style>& frame,
                        const char* caller) {
  if (frame.ndim() != 2) {
    throw py::value_error(std::string(caller) + ": a grey frame, a 2-D uint8 array (got " +
                          std::to_string(frame.ndim()) + " dimensions)");
  }
  return rt::ImageView{frame.data(), static_cast<int>(frame.shape(1)),
                       static_cast<int>(frame.shape(0)),
                       static_cast<std::ptrdiff_t>(frame.strides(0))};
}

py::array_t<double> points_array(const std::vector<Eigen::Vector2d>& points) {
  py::array_t<double> a({static_cast<py::ssize_t>(points.size()), py::ssize_t{2}});
  auto v = a.mutable_unchecked<2>();
  for (std::size_t i = 0; i < points.size(); ++i) {
    v(i, 0) = points[i].x();
    v(i, 1) = points[i].y();
  }
  return a;
}

template <typename T>
using RowMatrixOf = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

py::tuple xy(const Eigen::Vector2d& p) {
  return py::make_tuple(p.x(), p.y());
}

class PyTracker {
 public:
  explicit PyTracker(const py::object& init) {
    tools::TrackInit parsed;
    try {
      parsed = parse_source(init, "Tracker(init)", tools::parse_track_init);
    } catch (const tools::InputError& e) {
      throw py::value_error(e.what());
    }
    load_nodes_ = parsed.load_nodes;
    model_ = parsed.options.model;
    tracker_ = std::make_unique<rt::Tracker>(
        parsed.beam, parsed.options,
        model_ == rt::TrackerModel::kBeam ? parsed.load_nodes : std::vector<int>{});
    if (!tracker_->valid()) throw py::value_error(tracker_->error());
  }

  py::dict track(const py::array_t<std::uint8_t, py::array::c_style>& frame) {
    const rt::ImageView view = grey_view(frame, "Tracker.track");
    rt::FrameSummary s;
    {
      py::gil_scoped_release release;
      s = tracker_->track(view);
    }
    const int n = tracker_->num_nodes();
    py::array_t<double> nodes({n, 3}), forces({n, 3});
    auto nv = nodes.mutable_unchecked<2>();
    auto fv = forces.mutable_unchecked<2>();
    const Eigen::VectorXd& f = load_nodes_.empty() || model_ == rt::TrackerModel::kSnake
                                   ? tracker_->forces()
                                   : tracker_->fitted_loads();
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector2d x = tracker_->node_position(i);
      nv(i, 0) = x.x();
      nv(i, 1) = x.y();
      nv(i, 2) = tracker_->state()[3 * i + 2];
      for (int k = 0; k < 3; ++k) fv(i, k) = f[3 * i + k];
    }
    py::dict out;
    out["frame"] = frames_++;
    out["status"] = rt::to_string(s.status);
    out["nodes"] = nodes;
    out["forces"] = forces;
    out["rms_px"] = s.rms_px;
    out["verify_px"] = s.verified ? py::object(py::float_(s.verify_px)) : py::object(py::none());
    out["iterations"] = s.iterations;
    out["repetitions"] = s.repetitions;
    out["inlier_fraction"] = s.inlier_fraction;
    out["object_fraction"] = s.object_fraction;
    out["latency_us"] = s.seconds * 1e6;
    return out;
  }

  int num_nodes() const { return tracker_->num_nodes(); }

 private:
  std::unique_ptr<rt::Tracker> tracker_;
  std::vector<int> load_nodes_;
  rt::TrackerModel model_ = rt::TrackerModel::kBeam;
  long frames_ = 0;
};

// rt::detect_whiskers on one frame: the whiskers, and with keep_rejected the traces that were
// not, with the reason.
py::dict detect_whiskers(const py::array_t<std::uint8_t, py::array::c_style>& frame,
                         const std::string& face, double min_length_px, bool keep_rejected,
                         bool repair_traces) {
  rt::WhiskerDetectionOptions o;
  o.face = face_side(face);
  o.min_length_px = min_length_px;
  o.keep_rejected = keep_rejected;
  o.repair_traces = repair_traces;
  const rt::ImageView view = grey_view(frame, "detect_whiskers");
  rt::WhiskerDetection d;
  {
    py::gil_scoped_release release;
    d = rt::detect_whiskers(view, o);
  }
  if (!d.error.empty()) throw py::value_error(d.error);
  py::list whiskers, rejected;
  for (const auto& w : d.whiskers) {
    whiskers.append(py::dict(
        py::arg("points") = points_array(w.points), py::arg("follicle") = xy(w.follicle),
        py::arg("length_px") = w.length_px, py::arg("contrast_percent") = w.contrast_percent));
  }
  for (const auto& r : d.rejected) {
    rejected.append(
        py::dict(py::arg("points") = points_array(r.points), py::arg("reason") = r.reason));
  }
  return py::dict(py::arg("face") = rt::to_string(d.face), py::arg("backlight") = d.backlight,
                  py::arg("noise_percent") = d.noise_percent,
                  py::arg("seed_contrast") = d.seed_contrast,
                  py::arg("follow_contrast") = d.follow_contrast, py::arg("seeds") = d.seeds,
                  py::arg("whiskers") = whiskers, py::arg("rejected") = rejected);
}

#ifdef SINEW_PYTHON_OFFLINE
// sinew-register as a call: the case (a path or a dict) registered by offline::register_case, the
// result as numpy arrays and report.json's content; with out_dir, sinew-register's files too.
py::dict register_case(const py::object& source, const std::optional<std::string>& out_dir,
                       std::optional<int> max_iterations, bool quiet) {
  using Clock = std::chrono::steady_clock;
  const Clock::time_point run_start = Clock::now();
  offline::RegistrationCase c;
  tools::ScanImages scan;
  const tools::Log log(quiet);
  try {
    c = parse_source(source, "register(case)", tools::parse_registration_case);
    if (out_dir) scan = tools::read_scan_images(c, log);
  } catch (const tools::InputError& e) {
    throw py::value_error(e.what());
  }
  const double reading = common::seconds_since(run_start);
  offline::RegisterCaseOptions options;
  options.max_iterations = max_iterations;
  offline::RegisterCaseHooks hooks;
  hooks.message = [&](const std::string& line) { log.line("{}", line); };
  std::optional<tools::RegisterOutputs> out;
  if (out_dir) {
    out = tools::RegisterOutputs{std::filesystem::path(*out_dir)};
    hooks.prepared = [&](const offline::PreparedCase&) { tools::prepare_output_dir(*out, c); };
  }
  offline::RegisterCaseResult r;
  try {
    py::gil_scoped_release release;
    r = offline::register_case(c, options, hooks);
  } catch (const offline::RegistrationInputError& e) {
    throw py::value_error(e.what());
  } catch (const tools::InputError& e) {
    throw py::value_error(e.what());
  }
  const Clock::time_point writing_start = Clock::now();
  nlohmann::json report = tools::registration_report(c, r, c.case_path, 0);
  std::vector<std::string> written;
  if (out) {
    written = tools::write_result_files(*out, c, r, scan, report, log);
    tools::write_report(*out, r, reading, common::seconds_since(writing_start),
                        common::seconds_since(run_start), report, written);
  }
  const py::object json_loads = py::module_::import("json").attr("loads");
  py::dict result(py::arg("usable") = r.registration.summary.usable(),
                  py::arg("failed") = r.registration.summary.failed(),
                  py::arg("report") = json_loads(report.dump()), py::arg("written") = written);
  if (r.shape) {
    const RowMatrixOf<double> vertices = r.shape->surface.vertices;
    result["vertices"] = vertices;
    result["faces"] = RowMatrixOf<int>(r.shape->surface.triangles);
    result["tet_vertices"] = RowMatrixOf<double>(r.shape->mesh.vertices);
    result["tets"] = RowMatrixOf<int>(r.shape->mesh.tets);
    result["Fp"] = RowMatrixOf<double>(r.shape->Fp);
    result["marker_errors"] = r.shape->marker_errors;
  }
  return result;
}
#endif

// sinew-track --whiskers as a Python object (rt::WhiskerSession): the same results, frame by frame.
class PyWhiskers {
 public:
  PyWhiskers(const std::string& face, const std::string& redetect, double min_length_px,
             double mm_per_px, double young_modulus_gpa, double base_radius_um,
             double tip_radius_um, double length_mm, double axis_angle_deg,
             std::pair<double, double> curvature_window, int moment_elements, int rest_frame,
             int rest_frames, double associate_home_px, const std::string& whisker_preset,
             double start_clearance_px, double start_mean_surround_px, bool fit_follicle_position,
             bool profile_position, double held_ridge_px, double associate_contrast_ratio) {
    rt::WhiskerSessionOptions o;
    o.tracker.associate_home_px = associate_home_px;
    o.tracker.held_ridge_px = held_ridge_px;
    o.tracker.associate_contrast_ratio = associate_contrast_ratio;
    o.tracker.tracker.start_clearance_px = start_clearance_px;
    o.tracker.tracker.start_mean_surround_px = start_mean_surround_px;
    o.tracker.tracker.ridge_position_from_profile = profile_position;
    o.contact_fit.fit_base_translation = fit_follicle_position;
    o.detection.face = face_side(face);
    o.detection.min_length_px = min_length_px;
    o.redetect = redetect_mode(redetect);
    o.readout.physics.mm_per_px = mm_per_px;
    o.readout.physics.young_modulus_gpa = young_modulus_gpa;
    o.readout.physics.base_radius_um = base_radius_um;
    o.readout.physics.tip_radius_um = tip_radius_um;
    o.readout.physics.length_mm = length_mm;
    if (!whisker_preset.empty()) {
      // The preset's values where a keyword was left at its default.
      const auto preset = rt::whisker_preset(whisker_preset);
      if (!preset) throw py::value_error("whisker_preset: unknown name '" + whisker_preset + "'");
      const rt::WhiskerPhysics defaults;
      rt::WhiskerPhysics& p = o.readout.physics;
      if (young_modulus_gpa == defaults.young_modulus_gpa)
        p.young_modulus_gpa = preset->young_modulus_gpa;
      if (base_radius_um == defaults.base_radius_um) p.base_radius_um = preset->base_radius_um;
      if (tip_radius_um == defaults.tip_radius_um) p.tip_radius_um = preset->tip_radius_um;
      if (length_mm == defaults.length_mm) p.length_mm = preset->length_mm;
    }
    o.readout.axis_angle_deg = axis_angle_deg;
    o.readout.curvature_from_px = curvature_window.first;
    o.readout.curvature_to_px = curvature_window.second;
    o.readout.moment_elements = moment_elements;
    o.rest_frame = rest_frame;
    o.rest_frames = rest_frames;
    if (auto err = o.validate()) throw py::value_error(*err);
    si_ = o.readout.physics.si();
    session_ = std::make_unique<rt::WhiskerSession>(o);
  }

  py::dict track(const py::array_t<std::uint8_t, py::array::c_style>& frame) {
    const rt::ImageView view = grey_view(frame, "Whiskers.track");
    std::string error;
    {
      py::gil_scoped_release release;
      error = session_->process(view);
    }
    if (!error.empty()) throw py::value_error("frame " + std::to_string(frames_) + ": " + error);
    const rt::WhiskerTracker& tracker = session_->tracker();
    py::list whiskers;
    for (int w = 0; w < tracker.num_whiskers(); ++w) {
      const rt::Tracker& t = tracker.whisker(w);
      const rt::WhiskerFrame& r = tracker.result(w);
      py::array_t<double> nodes({t.num_nodes(), 3});
      auto nv = nodes.mutable_unchecked<2>();
      for (int i = 0; i < t.num_nodes(); ++i) {
        const Eigen::Vector2d x = t.node_position(i);
        nv(i, 0) = x.x();
        nv(i, 1) = x.y();
        nv(i, 2) = t.state()[3 * i + 2];
      }
      py::dict d;
      d["id"] = w;
      d["status"] = rt::to_string(r.status);
      d["nodes"] = nodes;
      d["follicle"] = xy(r.follicle);
      d["tip"] = xy(r.tip);
      d["length_px"] = r.length_px;
      d["on_neighbour"] = r.on_neighbour;
      d["jumped"] = r.jumped;
      d["out_of_order"] = r.out_of_order;
      d["reacquired"] = r.reacquired;
      d["inlier_fraction"] = r.summary.inlier_fraction;
      const rt::WhiskerSessionWhisker& sw = session_->whisker(w);
      if (sw.readout) {
        d["base_angle_deg"] = sw.readout->base_angle_deg;
        d[si_ ? "curvature_per_mm" : "curvature_per_px"] = sw.readout->curvature;
        d[si_ ? "delta_curvature_per_mm" : "delta_curvature_per_px"] = sw.readout->delta_curvature;
        d[si_ ? "m0_N_m" : "m0_model"] = sw.readout->moment;
        if (std::isfinite(sw.moment_sd)) d[si_ ? "m0_sd_N_m" : "m0_sd_model"] = sw.moment_sd;
      }
      if (sw.contact) {
        d["contact"] = sw.contact->touching;
        if (sw.contact->touching) {
          d["contact_arc_length_px"] = sw.contact->arc_length_px;
          d["contact_point"] = xy(sw.contact->point);
        }
      }
      if (sw.contact_load) {
        // Newtons and newton-metres with a scale, else model units (as the CLI's columns).
        const char* force_key = si_ ? "contact_force_N" : "contact_force_model";
        const char* moment_key = si_ ? "contact_moment_N_m" : "contact_moment_model";
        d[force_key] = xy(sw.contact_load->force);
        d[moment_key] = sw.contact_load->moment;
        d["contact_load_point"] = xy(sw.contact_load->point);
        d["contact_load_rms_px"] = sw.contact_load->rms_px;
        d["contact_load_converged"] = sw.contact_load->converged;
        d[si_ ? "pammer_force_N" : "pammer_force_model"] = sw.contact_load->pammer_force;
        d[si_ ? "pammer_moment_N_m" : "pammer_moment_model"] = sw.contact_load->pammer_moment;
        if (sw.contact_load->equilibrium) {
          d[si_ ? "contact_force_sd_N" : "contact_force_sd_model"] = sw.contact_load->force_sd;
          d[si_ ? "contact_moment_sd_N_m" : "contact_moment_sd_model"] = sw.contact_load->moment_sd;
          d["contact_load_noise_px"] = sw.contact_load->noise_px;
        }
      }
      if (const auto f = sw.follicle_force()) {
        d[si_ ? "follicle_force_axial_N" : "follicle_force_axial_model"] = f->x();
        d[si_ ? "follicle_force_lateral_N" : "follicle_force_lateral_model"] = f->y();
        const Eigen::Vector2d sd = *sw.follicle_force_sd();
        d[si_ ? "follicle_force_axial_sd_N" : "follicle_force_axial_sd_model"] = sd.x();
        d[si_ ? "follicle_force_lateral_sd_N" : "follicle_force_lateral_sd_model"] = sd.y();
      }
      whiskers.append(d);
    }
    py::dict out;
    out["frame"] = frames_++;
    out["latency_us"] = session_->tracking_seconds() * 1e6;
    out["whiskers"] = whiskers;
    if (session_->redetected()) {
      const rt::WhiskerAssociation& a = session_->association();
      out["redetect"] =
          py::dict(py::arg("ms") = session_->redetect_seconds() * 1e3,
                   py::arg("detected") = a.detected, py::arg("matched") = a.matched,
                   py::arg("restarted") = a.restarted, py::arg("shift") = xy(a.shift));
    }
    return out;
  }

  py::object detection() const {
    if (!session_->started()) return py::none();
    const rt::WhiskerDetection& d = session_->first_detection();
    py::list whiskers;
    for (const auto& w : d.whiskers) {
      whiskers.append(py::dict(
          py::arg("points") = points_array(w.points), py::arg("follicle") = xy(w.follicle),
          py::arg("length_px") = w.length_px, py::arg("contrast_percent") = w.contrast_percent));
    }
    return py::dict(py::arg("face") = rt::to_string(d.face), py::arg("backlight") = d.backlight,
                    py::arg("noise_percent") = d.noise_percent,
                    py::arg("seconds") = session_->first_detection_seconds(),
                    py::arg("whiskers") = whiskers);
  }

 private:
  std::unique_ptr<rt::WhiskerSession> session_;
  bool si_ = false;
  long frames_ = 0;
};

py::dict simulate(const py::object& beam) {
  std::optional<tools::SimulationCase> parsed;
  try {
    parsed.emplace(parse_source(beam, "simulate(beam)", tools::parse_simulation));
  } catch (const tools::InputError& e) {
    throw py::value_error(e.what());
  }
  const tools::SimulationCase& c = *parsed;
  tools::SimulationResult r;
  {
    py::gil_scoped_release release;
    r = tools::simulate(c);
  }
  const int n = c.model.num_nodes();
  py::array_t<double> nodes({n, 3});
  auto nv = nodes.mutable_unchecked<2>();
  const Eigen::Matrix2Xd x = c.model.current_positions(r.u);
  for (int i = 0; i < n; ++i) {
    nv(i, 0) = x(0, i);
    nv(i, 1) = x(1, i);
    nv(i, 2) = r.u[3 * i + 2];
  }
  py::dict out;
  out["nodes"] = nodes;
  out["converged"] = r.summary.converged();
  out["iterations"] = r.summary.iterations;
  out["status"] = common::to_string(r.summary.status);
  out["load_steps"] = r.summary.load_steps_taken;
  out["load_factor"] = r.summary.load_factor;
  out["residual"] = r.summary.residual_norm;
  return out;
}

}  // namespace

PYBIND11_MODULE(_sinew, m) {
  m.doc() = "Sinew: physics-based deformation from images (the real-time beam tracker).";
  py::class_<PyTracker>(m, "Tracker", R"doc(
A beam tracked through frames: its shape and the forces that bend it (seed 000).

Tracker(init) takes sinew-track's init file: a path, or the same content as a dict (nodes, fixed,
material, observation, half_width_px, load_nodes, options). Bad input raises ValueError naming the
field, as sinew-track reports it.
)doc")
      .def(py::init<const py::object&>(), py::arg("init"))
      .def("track", &PyTracker::track, py::arg("frame"), R"doc(
Tracks one grey frame (2-D uint8 numpy array, read in place). Returns a dict with the keys of
sinew-track's JSON lines: frame, status ('ok', 'not_converged', 'lost'), nodes (n x 3: x, y, theta),
forces (n x 3: fx, fy, m; the fitted loads when the init names load_nodes), rms_px, verify_px,
iterations, repetitions, inlier_fraction, object_fraction, latency_us (the C++ tracking time).
)doc")
      .def_property_readonly("num_nodes", &PyTracker::num_nodes);

  m.def("simulate", &simulate, py::arg("beam"), R"doc(
The static equilibrium of a geometrically nonlinear plane beam under loads, as sinew-simulate
computes it. beam: sinew-simulate's beam file, a path or the same content as a dict (nodes, fixed,
material, loads, steps, options). Returns a dict with the keys of sinew-simulate's output: nodes
(n x 3: x, y, theta), converged, iterations, status, load_steps, load_factor, residual.
)doc");

#ifdef SINEW_PYTHON_OFFLINE
  m.def("register", &register_case, py::arg("case"), py::arg("out_dir") = py::none(),
        py::arg("max_iterations") = py::none(), py::arg("quiet") = true, R"doc(
Registers a case as sinew-register does (offline::register_case): case is a case file's path or
the same content as a dict (relative file names then resolve against the working folder).
max_iterations overrides the case's stop.max_iterations; quiet=False prints the progress lines.
With out_dir, sinew-register's files are written there too (result_surface.obj, result.vtu,
report.json, plots). Returns a dict: usable, failed (not usable, or "stalled": sinew-register's
exit status 1), report (report.json's content), written (paths) and,
for a usable registration, vertices (n x 3) and faces (m x 3) of the deformed surface, tet_vertices
and tets of the deformed tet mesh, Fp (per tet, row-major 3x3 as 9 columns) and marker_errors, in
the case's units. Bad input raises ValueError with the one-line message sinew-register prints.
)doc");
#endif
  m.def("detect_whiskers", &detect_whiskers, py::arg("frame"), py::arg("face") = "auto",
        py::arg("min_length_px") = 40.0, py::arg("keep_rejected") = false,
        py::arg("repair_traces") = false, R"doc(
Finds the whiskers of one grey frame (2-D uint8 numpy array) with no initialisation, as
sinew-track --whiskers does on its first frame. Returns a dict: face, backlight, noise_percent,
seed_contrast, follow_contrast, seeds, whiskers (points n x 2 from the follicle, follicle,
length_px, contrast_percent) and, with keep_rejected, rejected (the traces that are not whiskers:
points and reason). repair_traces: as sinew-track --repair-traces (docs/tracker.md).
)doc");

  py::class_<PyWhiskers>(m, "Whiskers", R"doc(
Every whisker of a video, found on the first frame with no initialisation and tracked with stable
identities, their mechanics and their contacts: sinew-track --whiskers, frame by frame.

Whiskers(face='auto', redetect='every', min_length_px=40, mm_per_px=0, young_modulus_gpa=3.34,
base_radius_um=0, tip_radius_um=0, length_mm=0, axis_angle_deg=0, curvature_window=(0, 30),
moment_elements=3, rest_frame=0, rest_frames=1, associate_home_px=0, whisker_preset='',
start_clearance_px=0, start_mean_surround_px=0, fit_follicle_position=False,
profile_position=False, held_ridge_px=2, associate_contrast_ratio=2): the options of sinew-track --whiskers (docs/tracker.md). Without mm_per_px and
the radii, curvature and moment are in pixel model units. whisker_preset='rat-c2' or 'mouse-c2' takes
the modulus, radii and length from the literature (mouse-c2's modulus is the rat's: none is measured
in mice; docs/tracker.md); keywords given other values override them.
)doc")
      .def(py::init<const std::string&, const std::string&, double, double, double, double, double,
                    double, double, std::pair<double, double>, int, int, int, double,
                    const std::string&, double, double, bool, bool, double, double>(),
           py::arg("face") = "auto", py::arg("redetect") = "every", py::arg("min_length_px") = 40.0,
           py::arg("mm_per_px") = 0.0, py::arg("young_modulus_gpa") = 3.34,
           py::arg("base_radius_um") = 0.0, py::arg("tip_radius_um") = 0.0,
           py::arg("length_mm") = 0.0, py::arg("axis_angle_deg") = 0.0,
           py::arg("curvature_window") = std::pair<double, double>(0.0, 30.0),
           py::arg("moment_elements") = 3, py::arg("rest_frame") = 0, py::arg("rest_frames") = 1,
           py::arg("associate_home_px") = 0.0, py::arg("whisker_preset") = "",
           py::arg("start_clearance_px") = 0.0, py::arg("start_mean_surround_px") = 0.0,
           py::arg("fit_follicle_position") = false, py::arg("profile_position") = false,
           py::arg("held_ridge_px") = rt::WhiskerTrackerOptions{}.held_ridge_px,
           py::arg("associate_contrast_ratio") =
               rt::WhiskerTrackerOptions{}.associate_contrast_ratio)
      .def("track", &PyWhiskers::track, py::arg("frame"), R"doc(
Processes one grey frame (2-D uint8 numpy array, read in place): detection on the first, then
tracking, detection again and association (redetect), read-out and contact. Returns a dict with
the keys of sinew-track --whiskers' JSON lines: frame, latency_us (tracking only), whiskers (a list
of dicts: id, status, nodes (n x 3), follicle, tip, length_px, inlier_fraction, and for whiskers
tracked ok base_angle_deg, curvature, delta_curvature, m0 and contact; in contact after the rest
frame, the contact load: contact_force_model, contact_moment_model), redetect.
)doc")
      .def_property_readonly("detection", &PyWhiskers::detection,
                             "The first frame's detection (None before it): face, backlight, "
                             "whiskers with their traces (points, n x 2).");
}
