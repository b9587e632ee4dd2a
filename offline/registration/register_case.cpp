#include "offline/registration/register_case.hpp"

#include <fmt/core.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <utility>

#include "common/material/stable_neo_hookean.hpp"
#include "common/timing.hpp"
#include "offline/constraints/constraints.hpp"
#include "offline/meshing/surface_closest_point.hpp"
#include "offline/plastic/plastic_elastic_energy.hpp"
#include "offline/plastic/plastic_strain.hpp"
#include "offline/registration/marker_checks.hpp"
#include "offline/registration/surface_distance.hpp"
#include "offline/registration/template_surface.hpp"
#include "offline/registration/transfer.hpp"

namespace sinew::offline {

Eigen::MatrixXd CaseNormalisation::to_frame(const Eigen::MatrixXd& points) const {
  const double grid = std::ldexp(1.0, 40);
  return ((points.rowwise() - centre) / scale * grid).array().round() / grid;
}

Eigen::MatrixXd CaseNormalisation::scan_to_frame(const Eigen::MatrixXd& points,
                                                 bool free_object) const {
  if (!free_object) return to_frame(points);
  return (points.rowwise() - centre) / scale;
}

Eigen::MatrixXd CaseNormalisation::to_user(const Eigen::MatrixXd& points) const {
  return (points * scale).rowwise() + centre;
}

namespace {

using Clock = std::chrono::steady_clock;
using common::seconds_since;

// Template points farther than this from the tet mesh (in diagonals) are input errors: almost
// always a point in another frame or unit.
constexpr double kMaxEmbeddingDistance = 0.1;

// hooks.message, formatted.
class Messages {
 public:
  explicit Messages(const std::function<void(const std::string&)>& sink) : sink_(sink) {}
  template <typename... Args>
  void line(fmt::format_string<Args...> format, Args&&... args) const {
    if (sink_) sink_(fmt::format(format, std::forward<Args>(args)...));
  }

 private:
  const std::function<void(const std::string&)>& sink_;
};

// "12 s", "3.5 min", "2.1 h".
std::string duration(double seconds) {
  if (seconds < 10) return fmt::format("{:.1f} s", seconds);
  if (seconds < 90) return fmt::format("{:.0f} s", seconds);
  if (seconds < 5400) return fmt::format("{:.1f} min", seconds / 60);
  return fmt::format("{:.1f} h", seconds / 3600);
}

Eigen::MatrixXd positions(const Eigen::VectorXd& x) {
  return Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>(
      x.data(), x.size() / 3, 3);
}

// The template as read, in the case's units: a surface, or a tet mesh.
struct TemplateInput {
  io::SurfaceMesh surface;  // surface templates
  TetMesh tet_mesh;         // tet-mesh templates
  bool is_tet_mesh = false;
  Eigen::MatrixXd vertices() const {
    return is_tet_mesh ? Eigen::MatrixXd(tet_mesh.vertices) : surface.vertices;
  }
};

TemplateInput read_template(const RegistrationCase& c, CaseInputSummary& inputs,
                            const Messages& log) {
  TemplateInput t;
  t.is_tet_mesh = c.template_is_tet_mesh;
  if (c.template_is_tet_mesh) {
    TetMeshReadResult r = read_tet_mesh(c.template_path);
    if (!r.ok()) throw RegistrationInputError(r.error);
    t.tet_mesh = std::move(*r.mesh);
    log.line("template: tet mesh, {} vertices, {} tets{}", t.tet_mesh.vertices.rows(),
             t.tet_mesh.tets.rows(),
             r.flipped_tets > 0 ? fmt::format(" ({} tets reoriented)", r.flipped_tets) : "");
  } else {
    io::SurfaceMeshReadResult r = io::read_surface_mesh(c.template_path);
    if (!r.ok()) throw RegistrationInputError(r.error);
    t.surface = std::move(*r.mesh);
    log.line("template: surface, {} vertices, {} triangles{}", t.surface.vertices.rows(),
             t.surface.triangles.rows(),
             r.polygons_triangulated > 0
                 ? fmt::format(" ({} polygons triangulated)", r.polygons_triangulated)
                 : "");
    inputs.template_triangles = t.surface.triangles.rows();
  }
  inputs.template_vertices =
      c.template_is_tet_mesh ? t.tet_mesh.vertices.rows() : t.surface.vertices.rows();
  return t;
}

// The template's bounding box → the normalised frame; marker points far from the box are input
// errors, found before the slow meshing.
CaseNormalisation normalisation(const RegistrationCase& c, const Eigen::MatrixXd& vertices,
                                const std::string& u) {
  CaseNormalisation frame;
  const Eigen::RowVector3d lo = vertices.colwise().minCoeff();
  const Eigen::RowVector3d hi = vertices.colwise().maxCoeff();
  frame.centre = 0.5 * (lo + hi);
  frame.scale = (hi - lo).norm();
  if (!(frame.scale > 0) || !std::isfinite(frame.scale))
    throw RegistrationInputError(c.template_path + ": the template has no extent");
  check_markers_near_template(c, lo.transpose(), hi.transpose(), u);
  return frame;
}

// No attachments: a free object (§3.6), which needs markers to fix its pose.
void check_free_object(const RegistrationCase& c) {
  if (c.attachments.size() > 0 || c.landmarks.size() >= 3 || c.icp_markers.rows() >= 3) return;
  throw RegistrationInputError(
      c.case_path +
      ": no attachments, so the template is a free object (seed 003 §3.6), which "
      "needs at least 3 landmarks or 3 ICP markers to fix its pose; got " +
      std::to_string(c.landmarks.size()) + " landmarks and " +
      std::to_string(c.icp_markers.rows()) + " ICP markers");
}

// The tet mesh in the normalised frame: the template's own, or CGAL's of its surface.
TetMesh mesh_template(const RegistrationCase& c, const CaseNormalisation& frame, TemplateInput& t,
                      CaseInputSummary& inputs, const Messages& log) {
  TetMesh mesh;
  if (c.template_is_tet_mesh) {
    mesh = std::move(t.tet_mesh);
    mesh.vertices = frame.to_frame(mesh.vertices);
    return mesh;
  }
  log.line("meshing: CGAL Mesh_3, cell size {:.3g} of the diagonal", c.mesh.cell_size_fraction);
  const Eigen::MatrixXd v = frame.to_frame(t.surface.vertices);
  TetMesherResult meshed = make_tet_mesh(v, t.surface.triangles, c.mesh);
  if (!meshed.summary.ok()) {
    throw RegistrationInputError(c.template_path + ": cannot tet-mesh the template surface: " +
                                 (meshed.summary.message.empty()
                                      ? std::string(to_string(meshed.summary.status))
                                      : meshed.summary.message));
  }
  log.line("meshing: {}", meshed.summary.brief_report());
  inputs.mesher = meshed.summary;
  return std::move(meshed.mesh);
}

// Embeds template points (normalised) in the tet mesh; far points are input errors.
std::vector<EmbeddedPoint> embed(const TetPointLocator& locator, const Eigen::MatrixXd& points,
                                 const std::string& what, const std::string& source, double scale,
                                 const std::string& unit, double* worst_distance) {
  std::vector<EmbeddedPoint> out;
  out.reserve(static_cast<std::size_t>(points.rows()));
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    const Embedding e = locator.locate(points.row(i).transpose());
    if (!e.ok() || e.distance > kMaxEmbeddingDistance) {
      throw RegistrationInputError(fmt::format(
          "{}: {}[{}]: template point is {:.4g}{} from the template mesh ({:.1f}% of its "
          "diagonal); is it in the template's frame and units?",
          source, what, i, e.distance * scale, unit, 100 * e.distance));
    }
    *worst_distance = std::max(*worst_distance, e.distance);
    out.push_back(e.point);
  }
  return out;
}

// What the registration works with besides PreparedCase: built in place (the closest-point query
// and the energy keep pointers into it), never moved.
struct CaseWorkspace {
  std::optional<TetPointLocator> locator;
  std::optional<BoundarySurface> boundary;
  std::optional<SurfaceClosestPoint> surface_query;
  std::unique_ptr<ClosestSurfacePoint> closest;
  std::vector<std::vector<EmbeddedPoint>> transfer_points;
  std::optional<PlasticElasticEnergy> energy;
};

// Attachments (not for a free object), landmarks and ICP markers in the normalised frame.
RegistrationConstraints embed_constraints(const RegistrationCase& c, const PreparedCase& p,
                                          const TetPointLocator& locator, const std::string& u,
                                          double* worst) {
  const CaseNormalisation& frame = p.frame;
  RegistrationConstraints constraints;
  if (!p.free_object) {
    const auto points = embed(locator, frame.to_frame(c.attachments.template_points), "attachments",
                              c.attachments.source, frame.scale, u, worst);
    const Eigen::MatrixXd targets = frame.to_frame(c.attachments.target_points);
    for (std::size_t i = 0; i < points.size(); ++i) {
      PointConstraint pc;
      pc.kind = ConstraintKind::kAttachment;
      pc.point = points[i];
      pc.target = targets.row(static_cast<Eigen::Index>(i)).transpose();
      pc.weight = p.attachment_stiffness;
      constraints.attachments.push_back(pc);
    }
  }
  if (c.landmarks.size() > 0) {
    const auto points = embed(locator, frame.to_frame(c.landmarks.template_points), "landmarks",
                              c.landmarks.source, frame.scale, u, worst);
    const Eigen::MatrixXd targets = frame.scan_to_frame(c.landmarks.target_points, p.free_object);
    for (std::size_t i = 0; i < points.size(); ++i) {
      PointConstraint pc;
      pc.kind = ConstraintKind::kLandmark;
      pc.point = points[i];
      pc.target = targets.row(static_cast<Eigen::Index>(i)).transpose();
      constraints.landmarks.push_back(pc);
    }
  }
  const Eigen::MatrixXd markers = frame.scan_to_frame(c.icp_markers, p.free_object);
  for (Eigen::Index i = 0; i < markers.rows(); ++i)
    constraints.icp_markers.push_back(markers.row(i).transpose());
  return constraints;
}

// The output surface: template surface vertices as material points, or the mesh boundary; and
// the ICP closest points on it (tools' template surface when one was given, else the boundary).
void embed_output_surface(const RegistrationCase& c, const TemplateInput& t, const std::string& u,
                          PreparedCase& p, CaseWorkspace& ws, double* surface_worst) {
  if (!c.template_is_tet_mesh) {
    p.surface_points = embed(*ws.locator, p.frame.to_frame(t.surface.vertices), "vertices",
                             c.template_path, p.frame.scale, u, surface_worst);
    p.surface_triangles = t.surface.triangles;
  }
  BoundaryCheck boundary_check;
  ws.boundary = BoundarySurface::extract(p.rest.rows(), p.tets, &boundary_check);
  if (!ws.boundary) {
    throw RegistrationInputError(c.template_path +
                                 ": tet mesh boundary: " + boundary_check.message());
  }
  if (c.template_is_tet_mesh) {
    p.boundary_vertices = ws.boundary->vertices();
    std::vector<int> index(static_cast<std::size_t>(p.rest.rows()), -1);
    for (std::size_t i = 0; i < p.boundary_vertices.size(); ++i)
      index[static_cast<std::size_t>(p.boundary_vertices[i])] = static_cast<int>(i);
    p.surface_triangles.resize(ws.boundary->triangles().rows(), 3);
    for (Eigen::Index f = 0; f < p.surface_triangles.rows(); ++f)
      for (int k = 0; k < 3; ++k)
        p.surface_triangles(f, k) = index[static_cast<std::size_t>(ws.boundary->triangles()(f, k))];
  }
  if (p.constraints.icp_markers.empty()) return;
  if (!c.template_is_tet_mesh) {
    Eigen::VectorXd rest_dofs(3 * p.rest.rows());  // #V by 3 → vertex-major dofs
    for (Eigen::Index v = 0; v < p.rest.rows(); ++v)
      rest_dofs.segment<3>(3 * v) = p.rest.row(v).transpose();
    ws.closest = std::make_unique<TemplateSurfaceClosestPoint>(
        p.tets, rest_dofs, *ws.locator, p.surface_triangles, p.surface_points);
  } else {
    ws.surface_query = SurfaceClosestPoint::create(p.rest.rows(), p.tets, &boundary_check);
    if (!ws.surface_query)
      throw RegistrationInputError(c.template_path + ": " + boundary_check.message());
    ws.closest = std::make_unique<BoundaryClosestPoint>(*ws.surface_query);
  }
}

// Surfaces carried along (§4.3): every vertex embedded now, so a bad one stops the run before
// any work.
void embed_transfers(const RegistrationCase& c, const CaseNormalisation& frame,
                     const std::string& u, CaseWorkspace& ws) {
  ws.transfer_points.assign(c.transfer_paths.size(), {});
  for (std::size_t k = 0; k < c.transfer_paths.size(); ++k) {
    const std::string& path = c.transfer_paths[k];
    auto& points = ws.transfer_points[k];
    transfer_surface(path, "", [&](const Eigen::Vector3d& q, long index) {
      const Eigen::MatrixXd in_frame = frame.to_frame(q.transpose());
      const Embedding e = ws.locator->locate(in_frame.row(0).transpose());
      if (!e.ok() || e.distance > kMaxEmbeddingDistance) {
        throw RegistrationInputError(fmt::format(
            "{}: vertex {} is {:.4g}{} from the template mesh ({:.1f}% of its diagonal); a "
            "transferred surface must lie in the template",
            path, index, e.distance * frame.scale, u, 100 * e.distance));
      }
      points.push_back(e.point);
      return q;
    });
  }
}

// The registration's options from the case (lengths normalised); throws when invalid.
GaussNewtonOptions gauss_newton_options(const RegistrationCase& c, int max_iterations_per_stage,
                                        double scale, double* max_marker_error) {
  GaussNewtonOptions options;
  options.alpha = c.weights.alpha;
  const bool observations = c.landmarks.size() > 0 || c.icp_markers.rows() > 0;
  options.beta = c.weights.beta.value_or(observations ? 0.0 : 1e4);
  options.max_iterations_per_stage = max_iterations_per_stage;
  *max_marker_error = c.stop.max_marker_error.value_or(1e-3 * scale);
  options.max_marker_error = *max_marker_error / scale;
  options.min_step = c.stop.min_step;
  options.icp_weight_ramp = c.weights.icp_weight_ramp.value_or(
      default_icp_weight_ramp(c.landmarks.size() > 0 && c.weights.icp_stage_landmarks));
  options.icp_point_to_plane_iterations = c.weights.icp_point_to_plane_iterations;
  options.icp_stage_landmarks = c.weights.icp_stage_landmarks;
  options.landmark_stage = c.weights.landmark_stage;
  options.damped_step_trials = c.solver.damped_step_trials;
  options.predictor_warm_start = c.solver.predictor_warm_start;
  options.hold_clamped_tets = c.solver.hold_clamped_tets;
  options.icp_no_progress_iterations = c.stop.no_progress_iterations;
  options.eigenvalue_floor = c.solver.eigenvalue_floor;
  options.constant_strain_step_limit = c.solver.constant_strain_step_limit;
  options.rescue_min_damping = c.solver.rescue_min_damping;
  options.inverted_equilibrium_fallback = c.solver.inverted_equilibrium_fallback;
  options.equilibrium.cholesky_method = c.solver.cholesky;
  options.woodbury.cholesky_method = c.solver.cholesky;
  if (auto error = options.validate()) throw RegistrationInputError(c.case_path + ": " + *error);
  return options;
}

// The stages as the registration runs them (for the estimate of the time left).
std::vector<RegistrationStage> registration_stages(const PreparedCase& p) {
  std::vector<RegistrationStage> stages;
  const RegistrationConstraints& k = p.constraints;
  if (!p.free_object) stages.push_back(RegistrationStage::kAttachments);
  if (!k.landmarks.empty() &&
      (p.options.landmark_stage || k.icp_markers.empty() || !p.options.icp_stage_landmarks))
    stages.push_back(RegistrationStage::kLandmarks);
  if (!k.icp_markers.empty()) stages.push_back(RegistrationStage::kIcpMarkers);
  return stages;
}

// Everything between the normalised tet mesh and the registration: constraints, output surface,
// closest points, transfers, energy and options.
PreparedCase prepare(const RegistrationCase& c, const RegisterCaseOptions& run,
                     const TemplateInput& t, const CaseNormalisation& frame, TetMesh mesh,
                     CaseWorkspace& ws, CaseInputSummary& inputs, const Messages& log) {
  const std::string unit = to_string(c.units);
  const std::string u = unit.empty() ? "" : " " + unit;
  PreparedCase p;
  p.free_object = c.attachments.size() == 0;
  p.frame = frame;
  p.rest = std::move(mesh.vertices);
  p.tets = std::move(mesh.tets);
  p.attachment_stiffness = c.weights.attachment_stiffness;
  inputs.tet_vertices = p.rest.rows();
  inputs.tets = p.tets.rows();

  common::TetMeshCheck check;
  ws.locator = TetPointLocator::create(p.rest, p.tets, {}, &check);
  if (!ws.locator) throw RegistrationInputError(c.template_path + ": the tet mesh is invalid");
  double worst = 0.0, surface_worst = 0.0;
  p.constraints = embed_constraints(c, p, *ws.locator, u, &worst);
  embed_output_surface(c, t, u, p, ws, &surface_worst);
  log.line(
      "embedding: {} attachments, {} landmarks (farthest {:.3g}{} outside the mesh), {} "
      "surface points (farthest {:.3g}{})",
      p.constraints.attachments.size(), p.constraints.landmarks.size(), worst * frame.scale, u,
      c.template_is_tet_mesh ? p.boundary_vertices.size() : p.surface_points.size(),
      surface_worst * frame.scale, u);
  inputs.embedding_max_distance = worst * frame.scale;
  inputs.surface_embedding_max_distance = surface_worst * frame.scale;
  embed_transfers(c, frame, u, ws);

  // Unit material: μ = 1 (model), ν = 0.4 (E = 2μ_L(1 + ν) with μ_L = 3/4).
  common::StableNeoHookeanParameters material_parameters;
  material_parameters.poisson_ratio = 0.4;
  material_parameters.youngs_modulus = 2.0 * 0.75 * (1.0 + material_parameters.poisson_ratio);
  const auto material = common::StableNeoHookean::create(material_parameters);
  ws.energy = PlasticElasticEnergy::create(p.rest, p.tets, *material, {}, &check);
  if (!ws.energy) throw RegistrationInputError(c.template_path + ": the tet mesh is invalid");

  p.options = gauss_newton_options(c, run.max_iterations.value_or(c.stop.max_iterations_per_stage),
                                   frame.scale, &p.max_marker_error);
  p.stages = registration_stages(p);
  return p;
}

// One line per Gauss–Newton iteration, with an upper bound of the time left: the mean time of an
// iteration so far times the iterations the stages may still take (stages usually stop early).
class ProgressLines {
 public:
  ProgressLines(const PreparedCase& p, const GaussNewtonCheckpoint* resume, const Messages& log,
                const std::string& u)
      : p_(p), log_(log), u_(u) {
    if (resume != nullptr)
      for (const GaussNewtonIteration& it : resume->iterations) time(it);
  }
  void operator()(const GaussNewtonIteration& it) {
    time(it);
    std::string left;
    const auto at = std::find(p_.stages.begin(), p_.stages.end(), it.stage);
    if (iterations_timed_ > 0 && at != p_.stages.end()) {
      const long per_stage = static_cast<long>(p_.options.max_iterations_per_stage);
      const long remaining = std::max(0L, per_stage - static_cast<long>(it.iteration)) +
                             per_stage * static_cast<long>(p_.stages.end() - at - 1);
      left = fmt::format("  at most {} left",
                         duration(remaining * iteration_seconds_ / iterations_timed_));
    }
    const double scale = p_.frame.scale;
    log_.line(
        "  {:<11} {:>3}  objective {:.4e}  step {:.3f}  marker error mean {:.4g} max {:.4g}{}"
        "  {:>2} solves  {:.1f} s{}",
        to_string(it.stage), it.iteration, it.objective, it.step, it.marker_error_mean * scale,
        it.marker_error_max * scale, u_, it.equilibrium_solves, it.seconds, left);
  }

 private:
  void time(const GaussNewtonIteration& it) {
    if (it.stage == RegistrationStage::kInitialFit) return;
    iteration_seconds_ += it.seconds;
    ++iterations_timed_;
  }
  const PreparedCase& p_;
  const Messages& log_;
  std::string u_;
  double iteration_seconds_ = 0.0;
  int iterations_timed_ = 0;
};

void log_start(const PreparedCase& p, const RegisterCaseOptions& run, const Messages& log,
               const std::string& u) {
  log.line(
      "registering: {} tets, {} plastic dofs, alpha {:g}, beta {:g}, attachment stiffness "
      "{:g}, ICP tolerance {:.3g}{}",
      p.tets.rows(), 6 * p.tets.rows(), p.options.alpha, p.options.beta, p.attachment_stiffness,
      p.max_marker_error, u);
  log.line("mode: {}", p.free_object ? "free object (no attachments: rigid frame fitted, §3.6)"
                                     : "attached object");
  if (!run.resuming) return;
  const GaussNewtonCheckpoint* resume = run.resume;
  if (resume == nullptr) {
    log.line(
        "resuming: the run stopped before its initial fit was done; registering from the "
        "start");
  } else if (resume->next_stage) {
    log.line("resuming at stage {} iteration {} ({} iterations done, {:.1f} s of registration)",
             to_string(*resume->next_stage), resume->next_iteration, resume->iterations.size(),
             resume->seconds);
  } else {
    log.line("resuming after the last stage ({} iterations done): writing the outputs",
             resume->iterations.size());
  }
}

RegistrationResult run_registration(const PreparedCase& p, CaseWorkspace& ws,
                                    const RegisterCaseOptions& run, const RegisterCaseHooks& hooks,
                                    const Messages& log, const std::string& u) {
  log_start(p, run, log, u);
  ProgressLines lines(p, run.resume, log, u);
  const GaussNewtonProgress progress = [&](const GaussNewtonIteration& it) {
    lines(it);
    if (hooks.iteration) hooks.iteration(it);
  };
  RegistrationResult result =
      p.free_object ? register_free(*ws.energy, p.constraints, ws.closest.get(), p.options,
                                    progress, hooks.checkpoint, run.resume)
                    : register_attached(*ws.energy, p.constraints, ws.closest.get(), p.options,
                                        progress, hooks.checkpoint, run.resume);
  const GaussNewtonSummary& summary = result.summary;
  log.line("registration: {} ({}), final marker error mean {:.4g} max {:.4g}{}, {:.1f} s",
           to_string(summary.termination), summary.message.empty() ? "-" : summary.message,
           summary.marker_error_mean * p.frame.scale, summary.marker_error_max * p.frame.scale, u,
           summary.seconds);
  return result;
}

// The landmarks at the result (the ICP stage may or may not have kept them), case units.
ErrorStats landmark_errors(const PreparedCase& p, const Eigen::VectorXd& x) {
  double sum = 0.0, largest = 0.0;
  for (const PointConstraint& pc : p.constraints.landmarks) {
    const double e = (embedded_position(p.tets, pc.point, x) - pc.target).norm() * p.frame.scale;
    sum += e;
    largest = std::max(largest, e);
  }
  return {sum / static_cast<double>(p.constraints.landmarks.size()), largest};
}

io::SurfaceMesh deformed_surface(const PreparedCase& p, const Eigen::VectorXd& x) {
  io::SurfaceMesh deformed;
  if (!p.boundary_vertices.empty()) {
    deformed.vertices.resize(static_cast<Eigen::Index>(p.boundary_vertices.size()), 3);
    for (std::size_t i = 0; i < p.boundary_vertices.size(); ++i)
      deformed.vertices.row(static_cast<Eigen::Index>(i)) =
          x.segment<3>(3 * p.boundary_vertices[i]).transpose();
  } else {
    deformed.vertices.resize(static_cast<Eigen::Index>(p.surface_points.size()), 3);
    for (std::size_t i = 0; i < p.surface_points.size(); ++i)
      deformed.vertices.row(static_cast<Eigen::Index>(i)) =
          embedded_position(p.tets, p.surface_points[i], x).transpose();
  }
  deformed.vertices = p.frame.to_user(deformed.vertices);
  deformed.triangles = p.surface_triangles;
  return deformed;
}

// Where the data pins the result (offline/registration/marker_coverage.hpp): the final stage's
// markers (ICP markers, else landmarks) and the attachments' targets, all in the normalised frame.
MarkerCoverage result_coverage(const RegistrationConstraints& constraints,
                               const Eigen::MatrixXd& vertices, const Eigen::MatrixXi& triangles) {
  std::vector<Eigen::Vector3d> pinned;
  std::size_t markers = constraints.icp_markers.size();
  if (markers == 0) {
    for (const PointConstraint& pc : constraints.landmarks) pinned.push_back(pc.target);
    markers = pinned.size();
  }
  for (const PointConstraint& pc : constraints.attachments) pinned.push_back(pc.target);
  return marker_coverage(vertices, triangles, pinned, constraints.icp_markers, markers);
}

// Per tet: Fp, its eigenvalues, their ratio and its determinant.
void plastic_field(const Eigen::VectorXd& s, Eigen::Index num_tets, RegisteredShape& shape) {
  shape.Fp.resize(num_tets, 9);
  shape.principal_stretches.resize(num_tets, 3);
  shape.det_Fp.resize(num_tets);
  shape.stretch_ratio.resize(num_tets);
  for (Eigen::Index t = 0; t < num_tets; ++t) {
    const Eigen::Matrix3d F = plastic_strain_matrix(s.segment<6>(6 * t));
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) shape.Fp(t, 3 * i + j) = F(i, j);
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(F, Eigen::EigenvaluesOnly);
    shape.principal_stretches.row(t) = eig.eigenvalues().transpose();
    shape.stretch_ratio[t] = eig.eigenvalues().maxCoeff() / eig.eigenvalues().minCoeff();
    shape.det_Fp[t] = F.determinant();
  }
}

// Figs. 16: the final marker errors, case units.
std::vector<double> final_marker_errors(const PreparedCase& p, CaseWorkspace& ws,
                                        const Eigen::VectorXd& x) {
  std::vector<double> errors;
  const RegistrationConstraints& k = p.constraints;
  if (!k.icp_markers.empty()) {
    ws.closest->update(x);
    for (const Eigen::Vector3d& z : k.icp_markers) {
      const Eigen::Vector3d q = embedded_position(p.tets, ws.closest->closest(z), x);
      errors.push_back((q - z).norm() * p.frame.scale);
    }
    return errors;
  }
  const auto& list = k.landmarks.empty() ? k.attachments : k.landmarks;
  for (const PointConstraint& pc : list)
    errors.push_back((embedded_position(p.tets, pc.point, x) - pc.target).norm() * p.frame.scale);
  return errors;
}

void log_coverage(const RegisteredShape& shape, double scale, const Messages& log,
                  const std::string& u) {
  const MarkerCoverage& coverage = shape.coverage;
  const double spacings = MarkerCoverageOptions{}.uncovered_spacings;
  const Eigen::RowVector3d weakest = shape.mesh.vertices.row(coverage.weakest_vertex);
  log.line(
      "coverage: {:.1f}% of the surface is farther than {} marker spacings ({:.3g}{}) from "
      "every marker and attachment, {:.1f}% is held weakly along its normal (ICP markers hold "
      "the surface only along theirs); the weakest point is at ({:.4g}, {:.4g}, {:.4g}){}",
      100 * coverage.uncovered_area_fraction, spacings, spacings * coverage.nominal_spacing * scale,
      u, 100 * coverage.weakly_pinned_area_fraction, weakest.x(), weakest.y(), weakest.z(),
      coverage.weakly_pinned_area_fraction > 0 || coverage.uncovered_area_fraction > 0
          ? ". The shape there comes from the smoothness term, not from the data: result.vtu's "
            "marker_pinning and distance_to_nearest_marker show where markers would help"
          : "");
}

// The result in the case's units with its figures (a usable registration).
RegisteredShape registered_shape(const PreparedCase& p, CaseWorkspace& ws,
                                 const RegistrationResult& result, const Messages& log,
                                 const std::string& u) {
  const CaseNormalisation& frame = p.frame;
  RegisteredShape shape;
  shape.surface = deformed_surface(p, result.x);
  shape.mesh.vertices = frame.to_user(positions(result.x));
  shape.mesh.tets = p.tets;
  // Where the markers hold the surface and where the smoothness term alone shapes it.
  shape.coverage = result_coverage(p.constraints, positions(result.x), ws.boundary->triangles());
  log_coverage(shape, frame.scale, log, u);
  plastic_field(result.s, p.tets.rows(), shape);
  // Fig. 17: the tets' shape before (the template mesh) and after (deformed).
  shape.rest_mesh.vertices = frame.to_user(p.rest);
  shape.rest_mesh.tets = p.tets;
  shape.template_quality = tet_mesh_quality(shape.rest_mesh);
  shape.result_quality = tet_mesh_quality(shape.mesh);
  log.line(
      "tet quality: smallest dihedral angle {:.1f} deg in the template, {:.1f} deg in the "
      "result ({} inverted tets)",
      shape.template_quality.min_dihedral_degrees, shape.result_quality.min_dihedral_degrees,
      shape.result_quality.inverted_tets);
  for (const std::vector<EmbeddedPoint>& points : ws.transfer_points) {
    Eigen::MatrixXd moved(static_cast<Eigen::Index>(points.size()), 3);
    for (std::size_t i = 0; i < points.size(); ++i) {
      const Eigen::Vector3d q = embedded_position(p.tets, points[i], result.x);
      moved.row(static_cast<Eigen::Index>(i)) = frame.to_user(q.transpose()).row(0);
    }
    shape.transferred.push_back(std::move(moved));
  }
  shape.marker_errors = final_marker_errors(p, ws, result.x);
  return shape;
}

}  // namespace

RegisterCaseResult register_case(const RegistrationCase& c, const RegisterCaseOptions& options,
                                 const RegisterCaseHooks& hooks) {
  const Messages log(hooks.message);
  const std::string unit = to_string(c.units);
  const std::string u = unit.empty() ? "" : " " + unit;
  RegisterCaseResult out;

  // ---- reading
  Clock::time_point start = Clock::now();
  TemplateInput t = read_template(c, out.inputs, log);
  const CaseNormalisation frame = normalisation(c, t.vertices(), u);
  out.inputs.bounding_box_diagonal = frame.scale;
  for (const std::string& note : c.notes) log.line("note: {}", note);
  log.line("markers: {} attachments, {} landmarks, {} ICP markers; template diagonal {:.4g}{}",
           c.attachments.size(), c.landmarks.size(), c.icp_markers.rows(), frame.scale, u);
  check_free_object(c);  // before the (slow) meshing
  out.seconds.reading = seconds_since(start);

  // ---- meshing (in the normalised frame)
  start = Clock::now();
  TetMesh mesh = mesh_template(c, frame, t, out.inputs, log);
  out.seconds.meshing = seconds_since(start);

  // ---- embedding
  start = Clock::now();
  CaseWorkspace ws;
  out.problem = prepare(c, options, t, frame, std::move(mesh), ws, out.inputs, log);
  out.seconds.embedding = seconds_since(start);
  const PreparedCase& p = out.problem;
  if (hooks.prepared) hooks.prepared(p);

  // ---- registration
  start = Clock::now();
  out.registration = run_registration(p, ws, options, hooks, log, u);
  out.seconds.registration = seconds_since(start);

  // ---- figures
  start = Clock::now();
  if (out.registration.summary.usable()) {
    if (!p.constraints.landmarks.empty()) {
      out.landmark_errors = landmark_errors(p, out.registration.x);
      log.line("landmarks at the result: mean {:.4g} max {:.4g}{}", out.landmark_errors->mean,
               out.landmark_errors->max, u);
    }
    out.shape = registered_shape(p, ws, out.registration, log, u);
  }
  out.seconds.figures = seconds_since(start);
  return out;
}

TruthDistances truth_distances(const io::SurfaceMesh& result, const io::SurfaceMesh& truth) {
  TruthDistances d;
  const SurfaceDistanceStats to_truth = vertex_to_surface_distances(result, truth);
  const SurfaceDistanceStats from_truth = vertex_to_surface_distances(truth, result);
  d.result_to_truth = {to_truth.mean, to_truth.max};
  d.truth_to_result = {from_truth.mean, from_truth.max};
  // The vertex means above weigh each surface by its mesh density; the peers' figure (issue 18)
  // is area-uniform: 30,000 samples on each surface, mean over both.
  const SymmetricSurfaceDistance sampled = sampled_surface_distance(result, truth);
  d.result_samples_to_truth = {sampled.a_to_b.mean, sampled.a_to_b.max};
  d.truth_samples_to_result = {sampled.b_to_a.mean, sampled.b_to_a.max};
  d.symmetric_mean_area_sampled = sampled.mean;
  d.samples_per_surface = sampled.samples;
  return d;
}

}  // namespace sinew::offline
