#include "tools/register/case_file.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <sstream>

#include "offline/io/point_list_io.hpp"
#include "tools/io/json_file.hpp"

namespace sinew::tools {
namespace {

namespace fs = std::filesystem;

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

std::string number(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

// A file named in the case, relative to the case file's folder unless absolute.
std::string resolve(const std::string& case_path, const JsonCursor& field) {
  const std::string name = field.string();
  if (name.empty()) field.fail("must name a file (it is empty)");
  const fs::path p(name);
  if (p.is_absolute()) return p.string();
  return (fs::path(case_path).parent_path() / p).lexically_normal().string();
}

// An integer field in [lo, hi]; otherwise a one-line error naming the field and the range.
int integer_in(const JsonCursor& field, long lo, long hi) {
  const long v = field.integer();
  if (v < lo || v > hi) {
    field.fail("= " + std::to_string(v) + " must be in [" + std::to_string(lo) + ", " +
               std::to_string(hi) + "]");
  }
  return static_cast<int>(v);
}

Eigen::Vector3d parse_xyz(const JsonCursor& c) {
  if (!c.value().is_array() || c.value().size() != 3) c.fail("must be [x, y, z]");
  return {c.at(std::size_t{0}).finite_number(), c.at(std::size_t{1}).finite_number(),
          c.at(std::size_t{2}).finite_number()};
}

// Shared state while reading the marker files of one case.
class MarkerReader {
 public:
  explicit MarkerReader(RegistrationCase& c) : case_(c) {}

  PointPairSet pairs(const JsonCursor& field) {
    PointPairSet set;
    const nlohmann::json& v = field.value();
    if (v.is_string()) {
      const std::string file = resolve(case_.case_path, field);
      const offline::io::PointPairsReadResult r = offline::io::read_point_pairs(file);
      if (!r.ok()) throw InputError(r.error);
      set.template_points = r.pairs->template_points;
      set.target_points = r.pairs->target_points;
      set.labels = r.pairs->labels;
      set.source = set.template_source = file;
      return set;
    }
    if (v.is_object()) {
      field.expect_keys({"template", "target"});
      const JsonCursor t = field.at("template"), y = field.at("target");
      if (!t.value().is_string() || !y.value().is_string()) {
        field.fail(
            "as an object must be {\"template\": FILE, \"target\": FILE} (point lists "
            "matched by order)");
      }
      offline::io::PointList a = list_file(t), b = list_file(y);
      if (a.points.rows() != b.points.rows()) {
        field.fail("has " + std::to_string(a.points.rows()) + " template points (" +
                   resolve(case_.case_path, t) + ") but " + std::to_string(b.points.rows()) +
                   " target points (" + resolve(case_.case_path, y) + ")");
      }
      set.template_points = a.points;
      set.target_points = b.points;
      set.labels = a.labels;
      set.source = resolve(case_.case_path, y);
      set.template_source = resolve(case_.case_path, t);
      return set;
    }
    const std::size_t n = field.array_size();
    if (n == 0) field.fail("is empty");
    set.template_points.resize(static_cast<Eigen::Index>(n), 3);
    set.target_points.resize(static_cast<Eigen::Index>(n), 3);
    bool any_label = false;
    for (std::size_t i = 0; i < n; ++i) {
      const JsonCursor e = field.at(i);
      if (!e.value().is_object())
        e.fail("must be {\"template\": [x, y, z], \"target\": [x, y, z]}");
      e.expect_keys({"template", "target", "label"});
      const auto row = static_cast<Eigen::Index>(i);
      set.template_points.row(row) = parse_xyz(e.at("template")).transpose();
      set.target_points.row(row) = parse_xyz(e.at("target")).transpose();
      set.labels.push_back(e.has("label") ? e.at("label").string() : "");
      any_label = any_label || !set.labels.back().empty();
    }
    if (!any_label) set.labels.clear();
    set.source = set.template_source = case_.case_path;
    return set;
  }

  Eigen::MatrixXd points(const JsonCursor& field, std::string* source) {
    if (field.value().is_string()) {
      offline::io::PointList list = list_file(field);
      *source = resolve(case_.case_path, field);
      return list.points;
    }
    const std::size_t n = field.array_size();
    if (n == 0) field.fail("is empty");
    Eigen::MatrixXd p(static_cast<Eigen::Index>(n), 3);
    for (std::size_t i = 0; i < n; ++i)
      p.row(static_cast<Eigen::Index>(i)) = parse_xyz(field.at(i)).transpose();
    *source = case_.case_path;
    return p;
  }

 private:
  // A point list file: Slicer files are in millimetres (scaled for "units": "m"); files stating a
  // coordinate system are converted to the first one stated in the case.
  offline::io::PointList list_file(const JsonCursor& field) {
    const std::string file = resolve(case_.case_path, field);
    offline::io::PointListReadResult r = offline::io::read_point_list(file);
    if (!r.ok()) throw InputError(r.error);
    offline::io::PointList list = std::move(*r.list);
    if (r.skipped_points > 0) {
      case_.notes.push_back(file + ": skipped " + std::to_string(r.skipped_points) +
                            " control points without a defined position");
    }
    const std::string name = lower(file);
    const bool slicer = ends_with(name, ".fcsv") || ends_with(name, ".mrk.json");
    if (slicer && case_.units == LengthUnit::kMetre) {
      list.points *= 1e-3;
      case_.notes.push_back(file + ": 3D Slicer coordinates converted from mm to m");
    }
    using offline::io::CoordinateSystem;
    if (list.coordinate_system != CoordinateSystem::unspecified) {
      if (system_ == CoordinateSystem::unspecified) {
        system_ = list.coordinate_system;
        case_.coordinate_system = offline::io::to_string(system_);
      } else if (list.coordinate_system != system_) {
        const std::string from = offline::io::to_string(list.coordinate_system);
        std::string error;
        if (!offline::io::convert_coordinate_system(list, system_, &error))
          throw InputError(file + ": " + error);
        case_.notes.push_back(file + ": converted from " + from + " to " +
                              offline::io::to_string(system_));
      }
    }
    return list;
  }

  RegistrationCase& case_;
  offline::io::CoordinateSystem system_ = offline::io::CoordinateSystem::unspecified;
};

void parse_mesh_options(const JsonCursor& m, offline::TetMesherOptions& o) {
  m.expect_keys({"cell_size_fraction", "facet_distance_fraction", "facet_angle_degrees",
                 "cell_radius_edge_ratio", "odt", "lloyd", "smoothing_iterations", "perturb",
                 "exude", "sliver_bound_degrees", "protect_sharp_features", "feature_angle_degrees",
                 "random_seed", "max_vertices", "optimisation_time_limit_seconds",
                 "tets_across_thickness", "min_size_fraction", "thin_fraction_of_median"});
  auto real = [&](const char* key, double& out) {
    if (m.has(key)) out = m.at(key).finite_number();
  };
  auto flag = [&](const char* key, bool& out) {
    if (m.has(key)) out = m.at(key).boolean();
  };
  real("cell_size_fraction", o.cell_size_fraction);
  real("tets_across_thickness", o.tets_across_thickness);
  real("thin_fraction_of_median", o.thin_fraction_of_median);
  real("min_size_fraction", o.min_size_fraction);
  real("facet_distance_fraction", o.facet_distance_fraction);
  real("facet_angle_degrees", o.facet_angle_degrees);
  real("cell_radius_edge_ratio", o.cell_radius_edge_ratio);
  real("sliver_bound_degrees", o.sliver_bound_degrees);
  real("feature_angle_degrees", o.feature_angle_degrees);
  real("optimisation_time_limit_seconds", o.optimisation_time_limit_seconds);
  flag("odt", o.odt);
  flag("lloyd", o.lloyd);
  flag("perturb", o.perturb);
  flag("exude", o.exude);
  flag("protect_sharp_features", o.protect_sharp_features);
  if (m.has("smoothing_iterations"))
    o.smoothing_iterations = integer_in(m.at("smoothing_iterations"), 1, 1000);
  if (m.has("random_seed")) {
    const long v = m.at("random_seed").integer();
    if (v < 0 || v > 4294967295L) m.at("random_seed").fail("must be in [0, 2^32)");
    o.random_seed = static_cast<unsigned int>(v);
  }
  if (m.has("max_vertices")) o.max_vertices = m.at("max_vertices").integer();
  if (auto error = o.validate()) m.fail("invalid: " + *error);
}

}  // namespace

bool is_tet_mesh_path(const std::string& path) {
  const std::string name = lower(path);
  return ends_with(name, ".mesh") || ends_with(name, ".veg") || ends_with(name, ".node") ||
         ends_with(name, ".ele");
}

RegistrationCase read_registration_case(const std::string& path) {
  return parse_json_file(
      path, [&](const nlohmann::json& doc) { return parse_registration_case(doc, path); });
}

RegistrationCase parse_registration_case(const nlohmann::json& doc, const std::string& path) {
  const JsonCursor root(doc, path);
  root.expect_keys({"template", "units", "mesh", "attachments", "landmarks", "icp_markers",
                    "weights", "stop", "solver", "transfer", "scan_image"});
  RegistrationCase c;
  c.case_path = path;
  c.template_path = resolve(path, root.at("template"));
  c.template_is_tet_mesh = is_tet_mesh_path(c.template_path);

  if (root.has("units")) {
    const std::string u = root.at("units").string();
    if (u == "mm") {
      c.units = LengthUnit::kMillimetre;
    } else if (u == "m") {
      c.units = LengthUnit::kMetre;
    } else {
      root.at("units").fail("= \"" + u + "\" must be \"mm\" or \"m\"");
    }
  }

  if (root.has("mesh")) {
    if (c.template_is_tet_mesh) {
      root.at("mesh").fail("applies to surface templates only (" + c.template_path +
                           " is a tet mesh)");
    }
    parse_mesh_options(root.at("mesh"), c.mesh);
    c.mesh_options_given = true;
  }

  MarkerReader markers(c);
  // No attachments (absent or empty): an un-attached ("free-flying") object, §3.6.
  if (root.has("attachments")) c.attachments = markers.pairs(root.at("attachments"));
  if (root.has("landmarks")) c.landmarks = markers.pairs(root.at("landmarks"));
  c.icp_markers.resize(0, 3);
  if (root.has("icp_markers"))
    c.icp_markers = markers.points(root.at("icp_markers"), &c.icp_markers_source);

  if (root.has("transfer")) {
    const JsonCursor t = root.at("transfer");
    if (!t.value().is_array()) t.fail("must be a list of surface files");
    for (std::size_t i = 0; i < t.array_size(); ++i)
      c.transfer_paths.push_back(resolve(path, t.at(i)));
  }
  if (root.has("scan_image")) {
    const JsonCursor si = root.at("scan_image");
    si.expect_keys({"image", "mask", "label", "slices", "window"});
    RegistrationCase::ScanImage scan;
    if (!si.has("image")) si.fail("needs \"image\": the scan the slices are cut from");
    scan.image = resolve(path, si.at("image"));
    if (si.has("mask")) scan.mask = resolve(path, si.at("mask"));
    if (si.has("label")) scan.label = static_cast<int>(si.at("label").integer());
    if (si.has("slices")) scan.slices = integer_in(si.at("slices"), 1, 1000);
    if (si.has("window")) {
      const JsonCursor w = si.at("window");
      if (!w.value().is_array() || w.array_size() != 2) w.fail("must be [low, high]");
      scan.window_low = w.at(0).finite_number();
      scan.window_high = w.at(1).finite_number();
      if (!(scan.window_high > scan.window_low)) w.fail("must have low < high");
    }
    c.scan_image = scan;
  }
  if (root.has("weights")) {
    const JsonCursor w = root.at("weights");
    w.expect_keys({"alpha", "beta", "attachment_stiffness", "icp_weight_ramp",
                   "icp_point_to_plane_iterations", "icp_stage_landmarks", "landmark_stage"});
    if (w.has("alpha")) c.weights.alpha = w.at("alpha").positive_number();
    if (w.has("beta")) {
      const double beta = w.at("beta").finite_number();
      if (beta < 0) w.at("beta").fail("= " + number(beta) + " must be >= 0");
      c.weights.beta = beta;
    }
    if (w.has("attachment_stiffness"))
      c.weights.attachment_stiffness = w.at("attachment_stiffness").positive_number();
    if (w.has("icp_weight_ramp")) {
      const JsonCursor ramp = w.at("icp_weight_ramp");
      if (!ramp.value().is_array()) ramp.fail("must be a list of factors in (0, 1]");
      std::vector<double> factors;
      for (std::size_t i = 0; i < ramp.array_size(); ++i) {
        const double f = ramp.at(i).finite_number();
        if (!(f > 0 && f <= 1)) ramp.at(i).fail("= " + number(f) + " must be in (0, 1]");
        factors.push_back(f);
      }
      c.weights.icp_weight_ramp = factors;
    }
    if (w.has("icp_point_to_plane_iterations")) {
      c.weights.icp_point_to_plane_iterations =
          integer_in(w.at("icp_point_to_plane_iterations"), 0, 100000);
    }
    if (w.has("icp_stage_landmarks"))
      c.weights.icp_stage_landmarks = w.at("icp_stage_landmarks").boolean();
    if (w.has("landmark_stage")) c.weights.landmark_stage = w.at("landmark_stage").boolean();
  }
  if (root.has("solver")) {
    const JsonCursor v = root.at("solver");
    v.expect_keys({"damped_step_trials", "predictor_warm_start", "eigenvalue_floor", "cholesky",
                   "hold_clamped_tets", "constant_strain_step_limit", "rescue_min_damping",
                   "inverted_equilibrium_fallback"});
    if (v.has("cholesky")) {
      const std::string method = v.at("cholesky").string();
      if (method == "auto") {
        c.solver.cholesky = offline::SparseCholeskyMethod::kAuto;
      } else if (method == "simplicial") {
        c.solver.cholesky = offline::SparseCholeskyMethod::kSimplicial;
      } else if (method == "supernodal") {
        c.solver.cholesky = offline::SparseCholeskyMethod::kSupernodal;
      } else {
        v.at("cholesky")
            .fail("= \"" + method + "\" must be \"auto\", \"simplicial\" or \"supernodal\"");
      }
    }
    if (v.has("eigenvalue_floor")) {
      const double f = v.at("eigenvalue_floor").finite_number();
      if (!(f > 0 && f < 1)) v.at("eigenvalue_floor").fail("= " + number(f) + " must be in (0, 1)");
      c.solver.eigenvalue_floor = f;
    }
    if (v.has("predictor_warm_start"))
      c.solver.predictor_warm_start = v.at("predictor_warm_start").boolean();
    if (v.has("hold_clamped_tets"))
      c.solver.hold_clamped_tets = v.at("hold_clamped_tets").boolean();
    if (v.has("damped_step_trials"))
      c.solver.damped_step_trials = integer_in(v.at("damped_step_trials"), 0, 100);
    if (v.has("constant_strain_step_limit")) {
      const double f = v.at("constant_strain_step_limit").finite_number();
      if (!(f >= 0)) v.at("constant_strain_step_limit").fail("= " + number(f) + " must be >= 0");
      c.solver.constant_strain_step_limit = f;
    }
    if (v.has("rescue_min_damping")) {
      const double f = v.at("rescue_min_damping").finite_number();
      if (!(f >= 0)) v.at("rescue_min_damping").fail("= " + number(f) + " must be >= 0");
      c.solver.rescue_min_damping = f;
    }
    if (v.has("inverted_equilibrium_fallback"))
      c.solver.inverted_equilibrium_fallback = v.at("inverted_equilibrium_fallback").boolean();
  }
  if (root.has("stop")) {
    const JsonCursor s = root.at("stop");
    s.expect_keys({"max_iterations", "max_marker_error", "min_step", "no_progress_iterations"});
    if (s.has("no_progress_iterations")) {
      c.stop.no_progress_iterations = integer_in(s.at("no_progress_iterations"), 0, 100000);
    }
    if (s.has("max_iterations")) {
      c.stop.max_iterations_per_stage = integer_in(s.at("max_iterations"), 0, 100000);
    }
    if (s.has("max_marker_error")) {
      const double v = s.at("max_marker_error").finite_number();
      if (v < 0) s.at("max_marker_error").fail("= " + number(v) + " must be >= 0");
      c.stop.max_marker_error = v;
    }
    if (s.has("min_step")) {
      const double v = s.at("min_step").finite_number();
      if (!(v >= 0 && v < 1)) s.at("min_step").fail("= " + number(v) + " must be in [0, 1)");
      c.stop.min_step = v;
    }
  }
  return c;
}

}  // namespace sinew::tools
