// The Python module `sinew` (pybind11): the tracker a lab drives from its own Python loop.
//   tracker = sinew.Tracker("init.json")          # or the same content as a dict
//   result = tracker.track(frame)                  # 2-D uint8 numpy array (a grey frame)
// The frame is read in place (no copy); tracking runs without the GIL and allocates nothing in C++.
// Errors raise ValueError with the one-line message sinew-track prints.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <memory>
#include <string>

#include "rt/tracker.hpp"
#include "tools/track/track_init.hpp"

namespace py = pybind11;
using namespace sinew;

namespace {

class PyTracker {
 public:
  explicit PyTracker(const py::object& init) {
    tools::TrackInit parsed;
    try {
      if (py::isinstance<py::str>(init)) {
        parsed = tools::read_track_init(init.cast<std::string>());
      } else if (py::isinstance<py::dict>(init)) {
        const std::string text =
            py::module_::import("json").attr("dumps")(init).cast<std::string>();
        parsed = tools::parse_track_init(nlohmann::json::parse(text), "<init dict>");
      } else {
        throw py::type_error("Tracker(init): a path to an init JSON file or a dict");
      }
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
    if (frame.ndim() != 2) {
      throw py::value_error("Tracker.track: a grey frame, a 2-D uint8 array (got " +
                            std::to_string(frame.ndim()) + " dimensions)");
    }
    const rt::ImageView view{frame.data(), static_cast<int>(frame.shape(1)),
                             static_cast<int>(frame.shape(0)),
                             static_cast<std::ptrdiff_t>(frame.strides(0))};
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
}
