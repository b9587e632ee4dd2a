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
// why; no result files); 2 bad input or usage (one line on stderr naming the file, nothing
// written).
#include <fmt/core.h>
#include <CLI/CLI.hpp>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/material/stable_neo_hookean.hpp"
#include "common/timing.hpp"
#include "offline/constraints.hpp"
#include "offline/gauss_newton.hpp"
#include "offline/io/surface_mesh_io.hpp"
#include "offline/io/tet_mesh_io.hpp"
#include "offline/io/volume_image_io.hpp"
#include "offline/marker_coverage.hpp"
#include "offline/meshing/tet_mesher.hpp"
#include "offline/plastic_elastic_energy.hpp"
#include "offline/plastic_strain.hpp"
#include "offline/surface_closest_point.hpp"
#include "tools/io/json_file.hpp"
#include "tools/label/slice_pictures.hpp"
#include "tools/register/batch.hpp"
#include "tools/register/case_file.hpp"
#include "tools/register/checkpoint_file.hpp"
#include "tools/register/demo_case.hpp"
#include "tools/register/marker_checks.hpp"
#include "tools/register/plots.hpp"
#include "tools/register/surface_distance.hpp"
#include "tools/register/template_surface.hpp"
#include "tools/register/transfer.hpp"

namespace {

using namespace sinew;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

using common::seconds_since;

// Template points farther than this from the tet mesh (in diagonals) are input errors: almost
// always a point in another frame or unit.
constexpr double kMaxEmbeddingDistance = 0.1;

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

// x_normalised = (x − centre) / scale.
struct Normalisation {
  Eigen::RowVector3d centre = Eigen::RowVector3d::Zero();
  double scale = 1.0;
  // Rounded to multiples of 2⁻⁴⁰ (1e-12 of the diagonal) so that the same case in millimetres and
  // in metres gives bitwise the same normalised input, hence the same tet mesh (CGAL's
  // refinement is not continuous in its input).
  Eigen::MatrixXd to_frame(const Eigen::MatrixXd& points) const {
    const double grid = std::ldexp(1.0, 40);
    return ((points.rowwise() - centre) / scale * grid).array().round() / grid;
  }
  // The scan's points of a free object are not rounded here: register_free moves them onto the
  // template and rounds them there. Rounded in the scan's own frame, the same points in another
  // pose of the scan differ by up to half a step (5e-13) after that move and cross register_free's
  // grid far more often (with a 2⁻³⁰ grid there, sub-verse013 rotated by 180° became another run,
  // 7e-3 of the diagonal away).
  Eigen::MatrixXd scan_to_frame(const Eigen::MatrixXd& points, bool free_object) const {
    if (!free_object) return to_frame(points);
    return (points.rowwise() - centre) / scale;
  }
  Eigen::MatrixXd to_user(const Eigen::MatrixXd& points) const {
    return (points * scale).rowwise() + centre;
  }
};

// Embeds template points (normalised) in the tet mesh; far points are input errors.
std::vector<offline::EmbeddedPoint> embed(const offline::TetPointLocator& locator,
                                          const Eigen::MatrixXd& points, const std::string& what,
                                          const std::string& source, double scale,
                                          const std::string& unit, double* worst_distance) {
  std::vector<offline::EmbeddedPoint> out;
  out.reserve(static_cast<std::size_t>(points.rows()));
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    const offline::Embedding e = locator.locate(points.row(i).transpose());
    if (!e.ok() || e.distance > kMaxEmbeddingDistance) {
      throw tools::InputError(fmt::format(
          "{}: {}[{}]: template point is {:.4g}{} from the template mesh ({:.1f}% of its "
          "diagonal); is it in the template's frame and units?",
          source, what, i, e.distance * scale, unit, 100 * e.distance));
    }
    *worst_distance = std::max(*worst_distance, e.distance);
    out.push_back(e.point);
  }
  return out;
}

Eigen::MatrixXd positions(const Eigen::VectorXd& x) {
  return Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>(
      x.data(), x.size() / 3, 3);
}

// Where the data pins the result (offline/marker_coverage.hpp): the final stage's markers (ICP
// markers, else landmarks) and the attachments' targets, all in the normalised frame.
offline::MarkerCoverage result_coverage(const offline::RegistrationConstraints& constraints,
                                        const Eigen::MatrixXd& vertices,
                                        const Eigen::MatrixXi& triangles) {
  std::vector<Eigen::Vector3d> pinned;
  std::size_t markers = constraints.icp_markers.size();
  if (markers == 0) {
    for (const offline::PointConstraint& pc : constraints.landmarks) pinned.push_back(pc.target);
    markers = pinned.size();
  }
  for (const offline::PointConstraint& pc : constraints.attachments) pinned.push_back(pc.target);
  return offline::marker_coverage(vertices, triangles, pinned, constraints.icp_markers, markers);
}

nlohmann::json mesher_json(const offline::TetMesherSummary& s) {
  nlohmann::json j;
  j["status"] = offline::to_string(s.status);
  j["vertices"] = s.num_vertices;
  j["tets"] = s.num_tets;
  j["boundary_faces"] = s.num_boundary_faces;
  j["input_inward_oriented"] = s.input_inward_oriented;
  j["flipped_tets"] = s.flipped_tets;
  if (s.min_dihedral_degrees) j["min_dihedral_degrees"] = *s.min_dihedral_degrees;
  if (s.max_dihedral_degrees) j["max_dihedral_degrees"] = *s.max_dihedral_degrees;
  if (s.min_radius_ratio) j["min_radius_ratio"] = *s.min_radius_ratio;
  if (s.mean_radius_ratio) j["mean_radius_ratio"] = *s.mean_radius_ratio;
  j["time_limit_reached"] = s.time_limit_reached;
  j["seconds"] = s.seconds;
  return j;
}

struct Outputs {
  fs::path dir;
  fs::path surface() const { return dir / "result_surface.obj"; }
  fs::path vtu() const { return dir / "result.vtu"; }
  fs::path report() const { return dir / "report.json"; }
  fs::path checkpoint() const { return tools::checkpoint_path(dir); }
};

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

// 64-bit hash of a matrix's coefficients, as hex.
template <typename Matrix>
std::uint64_t hash_matrix(const Matrix& m, std::uint64_t hash = tools::kFnvOffset) {
  return tools::fnv1a(m.data(),
                      sizeof(typename Matrix::Scalar) * static_cast<std::size_t>(m.size()), hash);
}
std::uint64_t hash_points(const std::vector<offline::EmbeddedPoint>& points, std::uint64_t hash) {
  for (const offline::EmbeddedPoint& p : points) {
    const long long tet = static_cast<long long>(p.tet);
    hash = tools::fnv1a(&tet, sizeof tet, hash);
    hash = hash_matrix(p.weights, hash);
  }
  return hash;
}
std::uint64_t hash_constraints(const std::vector<offline::PointConstraint>& list,
                               std::uint64_t hash) {
  for (const offline::PointConstraint& c : list) {
    hash = hash_points({c.point}, hash);
    hash = hash_matrix(c.target, hash);
    hash = tools::fnv1a(&c.weight, sizeof c.weight, hash);
  }
  return hash;
}
std::string hex(std::uint64_t value) {
  return fmt::format("{:016x}", value);
}

// "12 s", "3.5 min", "2.1 h".
std::string duration(double seconds) {
  if (seconds < 10) return fmt::format("{:.1f} s", seconds);
  if (seconds < 90) return fmt::format("{:.0f} s", seconds);
  if (seconds < 5400) return fmt::format("{:.1f} min", seconds / 60);
  return fmt::format("{:.1f} h", seconds / 3600);
}

// Creates OUTDIR (after every input check) and proves it writable before the long run.
void prepare_output_dir(const Outputs& out) {
  std::error_code ec;
  if (fs::exists(out.dir, ec) && !fs::is_directory(out.dir, ec))
    throw tools::InputError(out.dir.string() + ": exists and is not a folder");
  fs::create_directories(out.dir, ec);
  if (ec)
    throw tools::InputError(out.dir.string() + ": cannot create folder (" + ec.message() + ")");
  const fs::path probe = out.dir / ".sinew-register-probe";
  std::FILE* f = std::fopen(probe.c_str(), "wb");
  if (f == nullptr) throw tools::InputError(out.dir.string() + ": folder is not writable");
  std::fclose(f);
  fs::remove(probe, ec);
}

int run(const RunRequest& request) {
  const std::string& case_path = request.case_file;
  const std::string& truth_path = request.truth_file;
  const bool quiet = request.quiet;
  const std::optional<int>& max_iterations = request.max_iterations;
  const Clock::time_point run_start = Clock::now();
  const Log log(quiet);
  nlohmann::json phases;

  // ---- reading
  Clock::time_point start = Clock::now();
  log.line("reading {}", case_path);
  tools::RegistrationCase c = tools::read_registration_case(case_path);
  if (max_iterations) c.stop.max_iterations_per_stage = *max_iterations;
  const std::string unit = tools::to_string(c.units);
  const std::string u = unit.empty() ? "" : " " + unit;

  offline::io::SurfaceMesh surface;  // template surface (user units), when a surface was given
  offline::TetMesh tet_mesh;         // user units until normalised below
  nlohmann::json inputs;
  inputs["template"] = c.template_path;
  if (c.template_is_tet_mesh) {
    offline::TetMeshReadResult r = offline::read_tet_mesh(c.template_path);
    if (!r.ok()) throw tools::InputError(r.error);
    tet_mesh = std::move(*r.mesh);
    log.line("template: tet mesh, {} vertices, {} tets{}", tet_mesh.vertices.rows(),
             tet_mesh.tets.rows(),
             r.flipped_tets > 0 ? fmt::format(" ({} tets reoriented)", r.flipped_tets) : "");
  } else {
    offline::io::SurfaceMeshReadResult r = offline::io::read_surface_mesh(c.template_path);
    if (!r.ok()) throw tools::InputError(r.error);
    surface = std::move(*r.mesh);
    log.line("template: surface, {} vertices, {} triangles{}", surface.vertices.rows(),
             surface.triangles.rows(),
             r.polygons_triangulated > 0
                 ? fmt::format(" ({} polygons triangulated)", r.polygons_triangulated)
                 : "");
    inputs["template_triangles"] = surface.triangles.rows();
  }
  std::optional<offline::io::SurfaceMesh> truth;  // --truth, checked before any work
  if (!truth_path.empty()) {
    offline::io::SurfaceMeshReadResult r = offline::io::read_surface_mesh(truth_path);
    if (!r.ok()) throw tools::InputError(r.error);
    truth = std::move(*r.mesh);
    log.line("truth: {}, {} vertices, {} triangles", request.truth_path, truth->vertices.rows(),
             truth->triangles.rows());
  }
  // "scan_image": read now, so that a bad image fails before any work.
  std::optional<offline::io::VolumeImage> scan_image, scan_mask;
  if (c.scan_image) {
    auto read_image = [&](const std::string& path) {
      offline::io::VolumeImageReadResult r = offline::io::read_volume_image(path);
      if (!r.image) throw tools::InputError(r.error);
      return std::move(*r.image);
    };
    scan_image = read_image(c.scan_image->image);
    if (!c.scan_image->mask.empty()) {
      scan_mask = read_image(c.scan_image->mask);
      if (scan_mask->size != scan_image->size) {
        throw tools::InputError(c.scan_image->mask + ": its voxel grid differs from " +
                                c.scan_image->image + "'s");
      }
    }
    log.line("scan image: {}, {} x {} x {} voxels{}", c.scan_image->image, scan_image->size.x(),
             scan_image->size.y(), scan_image->size.z(),
             scan_mask ? ", mask " + c.scan_image->mask : std::string());
  }
  const Eigen::MatrixXd template_vertices =
      c.template_is_tet_mesh ? Eigen::MatrixXd(tet_mesh.vertices) : surface.vertices;
  inputs["template_vertices"] = template_vertices.rows();

  Normalisation frame;
  {
    const Eigen::RowVector3d lo = template_vertices.colwise().minCoeff();
    const Eigen::RowVector3d hi = template_vertices.colwise().maxCoeff();
    frame.centre = 0.5 * (lo + hi);
    frame.scale = (hi - lo).norm();
    if (!(frame.scale > 0) || !std::isfinite(frame.scale))
      throw tools::InputError(c.template_path + ": the template has no extent");
    // Before the slow meshing: marker points in another frame or unit.
    tools::check_markers_near_template(c, lo.transpose(), hi.transpose(), u);
  }
  inputs["bounding_box_diagonal"] = frame.scale;
  inputs["attachments"] = c.attachments.size();
  inputs["landmarks"] = c.landmarks.size();
  inputs["icp_markers"] = c.icp_markers.rows();
  if (!c.coordinate_system.empty()) inputs["coordinate_system"] = c.coordinate_system;
  inputs["notes"] = c.notes;
  for (const std::string& note : c.notes) log.line("note: {}", note);
  log.line("markers: {} attachments, {} landmarks, {} ICP markers; template diagonal {:.4g}{}",
           c.attachments.size(), c.landmarks.size(), c.icp_markers.rows(), frame.scale, u);
  phases["reading"] = seconds_since(start);

  // No attachments: a free object (§3.6); checked before the (slow) meshing.
  const bool free_object = c.attachments.size() == 0;
  if (free_object && c.landmarks.size() < 3 && c.icp_markers.rows() < 3) {
    throw tools::InputError(
        case_path +
        ": no attachments, so the template is a free object (seed 003 §3.6), which "
        "needs at least 3 landmarks or 3 ICP markers to fix its pose; got " +
        std::to_string(c.landmarks.size()) + " landmarks and " +
        std::to_string(c.icp_markers.rows()) + " ICP markers");
  }

  // ---- meshing (in the normalised frame)
  start = Clock::now();
  if (c.template_is_tet_mesh) {
    tet_mesh.vertices = frame.to_frame(tet_mesh.vertices);
  } else {
    log.line("meshing: CGAL Mesh_3, cell size {:.3g} of the diagonal", c.mesh.cell_size_fraction);
    const Eigen::MatrixXd v = frame.to_frame(surface.vertices);
    offline::TetMesherResult meshed = offline::make_tet_mesh(v, surface.triangles, c.mesh);
    if (!meshed.summary.ok()) {
      throw tools::InputError(c.template_path + ": cannot tet-mesh the template surface: " +
                              (meshed.summary.message.empty()
                                   ? std::string(offline::to_string(meshed.summary.status))
                                   : meshed.summary.message));
    }
    log.line("meshing: {}", meshed.summary.brief_report());
    inputs["mesher"] = mesher_json(meshed.summary);
    tet_mesh = std::move(meshed.mesh);
  }
  const Eigen::MatrixXd rest = tet_mesh.vertices;
  const common::TetIndices tets = tet_mesh.tets;
  inputs["tet_vertices"] = rest.rows();
  inputs["tets"] = tets.rows();
  phases["meshing"] = seconds_since(start);

  // ---- embedding
  start = Clock::now();
  common::TetMeshCheck check;
  auto locator = offline::TetPointLocator::create(rest, tets, {}, &check);
  if (!locator) throw tools::InputError(c.template_path + ": the tet mesh is invalid");
  double worst = 0.0;
  offline::RegistrationConstraints constraints;
  const double stiffness = c.weights.attachment_stiffness;
  if (!free_object) {
    const auto points = embed(*locator, frame.to_frame(c.attachments.template_points),
                              "attachments", c.attachments.source, frame.scale, u, &worst);
    const Eigen::MatrixXd targets = frame.to_frame(c.attachments.target_points);
    for (std::size_t i = 0; i < points.size(); ++i) {
      offline::PointConstraint pc;
      pc.kind = offline::ConstraintKind::kAttachment;
      pc.point = points[i];
      pc.target = targets.row(static_cast<Eigen::Index>(i)).transpose();
      pc.weight = stiffness;
      constraints.attachments.push_back(pc);
    }
  }
  if (c.landmarks.size() > 0) {
    const auto points = embed(*locator, frame.to_frame(c.landmarks.template_points), "landmarks",
                              c.landmarks.source, frame.scale, u, &worst);
    const Eigen::MatrixXd targets = frame.scan_to_frame(c.landmarks.target_points, free_object);
    for (std::size_t i = 0; i < points.size(); ++i) {
      offline::PointConstraint pc;
      pc.kind = offline::ConstraintKind::kLandmark;
      pc.point = points[i];
      pc.target = targets.row(static_cast<Eigen::Index>(i)).transpose();
      constraints.landmarks.push_back(pc);
    }
  }
  const Eigen::MatrixXd markers = frame.scan_to_frame(c.icp_markers, free_object);
  for (Eigen::Index i = 0; i < markers.rows(); ++i)
    constraints.icp_markers.push_back(markers.row(i).transpose());

  // The output surface: template surface vertices as material points, or the mesh boundary.
  std::vector<offline::EmbeddedPoint> surface_points;
  Eigen::MatrixXi surface_triangles;
  std::vector<int> boundary_vertices;  // tet-mesh template: mesh vertex of each output vertex
  double surface_worst = 0.0;
  if (!c.template_is_tet_mesh) {
    surface_points = embed(*locator, frame.to_frame(surface.vertices), "vertices", c.template_path,
                           frame.scale, u, &surface_worst);
    surface_triangles = surface.triangles;
  }
  offline::BoundaryCheck boundary_check;
  auto boundary = offline::BoundarySurface::extract(rest.rows(), tets, &boundary_check);
  if (!boundary) {
    throw tools::InputError(c.template_path + ": tet mesh boundary: " + boundary_check.message());
  }
  if (c.template_is_tet_mesh) {
    boundary_vertices = boundary->vertices();
    std::vector<int> index(static_cast<std::size_t>(rest.rows()), -1);
    for (std::size_t i = 0; i < boundary_vertices.size(); ++i)
      index[static_cast<std::size_t>(boundary_vertices[i])] = static_cast<int>(i);
    surface_triangles.resize(boundary->triangles().rows(), 3);
    for (Eigen::Index f = 0; f < surface_triangles.rows(); ++f)
      for (int k = 0; k < 3; ++k)
        surface_triangles(f, k) = index[static_cast<std::size_t>(boundary->triangles()(f, k))];
  }
  // ICP closest points: on the template surface itself when one was given (the surface that is
  // written; tools/register/template_surface.hpp), else on the tet mesh's boundary.
  std::optional<offline::SurfaceClosestPoint> surface_query;
  std::unique_ptr<offline::ClosestSurfacePoint> closest;
  if (!constraints.icp_markers.empty() && !c.template_is_tet_mesh) {
    const Eigen::MatrixXd rest_rows = rest;  // #V by 3 → vertex-major dofs
    Eigen::VectorXd rest_dofs(3 * rest_rows.rows());
    for (Eigen::Index v = 0; v < rest_rows.rows(); ++v)
      rest_dofs.segment<3>(3 * v) = rest_rows.row(v).transpose();
    closest = std::make_unique<tools::TemplateSurfaceClosestPoint>(
        tets, rest_dofs, *locator, surface_triangles, surface_points);
  } else if (!constraints.icp_markers.empty()) {
    surface_query = offline::SurfaceClosestPoint::create(rest.rows(), tets, &boundary_check);
    if (!surface_query) throw tools::InputError(c.template_path + ": " + boundary_check.message());
    closest = std::make_unique<offline::BoundaryClosestPoint>(*surface_query);
  }
  log.line(
      "embedding: {} attachments, {} landmarks (farthest {:.3g}{} outside the mesh), {} "
      "surface points (farthest {:.3g}{})",
      constraints.attachments.size(), constraints.landmarks.size(), worst * frame.scale, u,
      c.template_is_tet_mesh ? boundary_vertices.size() : surface_points.size(),
      surface_worst * frame.scale, u);
  inputs["embedding_max_distance"] = worst * frame.scale;
  inputs["surface_embedding_max_distance"] = surface_worst * frame.scale;
  // Surfaces carried along (§4.3): every vertex embedded now, so a bad one stops the run before
  // any work (and before OUTDIR exists).
  std::vector<std::vector<offline::EmbeddedPoint>> transfer_points(c.transfer_paths.size());
  for (std::size_t k = 0; k < c.transfer_paths.size(); ++k) {
    const std::string& path = c.transfer_paths[k];
    auto& points = transfer_points[k];
    tools::transfer_surface(path, "", [&](const Eigen::Vector3d& p, long index) {
      const Eigen::MatrixXd in_frame = frame.to_frame(p.transpose());
      const offline::Embedding e = locator->locate(in_frame.row(0).transpose());
      if (!e.ok() || e.distance > kMaxEmbeddingDistance) {
        throw tools::InputError(fmt::format(
            "{}: vertex {} is {:.4g}{} from the template mesh ({:.1f}% of its diagonal); a "
            "transferred surface must lie in the template",
            path, index, e.distance * frame.scale, u, 100 * e.distance));
      }
      points.push_back(e.point);
      return p;
    });
  }

  // Unit material: μ = 1 (model), ν = 0.4 (E = 2μ_L(1 + ν) with μ_L = 3/4).
  common::StableNeoHookeanParameters material_parameters;
  material_parameters.poisson_ratio = 0.4;
  material_parameters.youngs_modulus = 2.0 * 0.75 * (1.0 + material_parameters.poisson_ratio);
  const auto material = common::StableNeoHookean::create(material_parameters);
  auto energy = offline::PlasticElasticEnergy::create(rest, tets, *material, {}, &check);
  if (!energy) throw tools::InputError(c.template_path + ": the tet mesh is invalid");
  phases["embedding"] = seconds_since(start);

  offline::GaussNewtonOptions options;
  options.alpha = c.weights.alpha;
  const bool observations = c.landmarks.size() > 0 || c.icp_markers.rows() > 0;
  options.beta = c.weights.beta.value_or(observations ? 0.0 : 1e4);
  options.max_iterations_per_stage = c.stop.max_iterations_per_stage;
  const double max_marker_error = c.stop.max_marker_error.value_or(1e-3 * frame.scale);
  options.max_marker_error = max_marker_error / frame.scale;
  options.min_step = c.stop.min_step;
  options.icp_weight_ramp = c.weights.icp_weight_ramp;
  options.icp_point_to_plane_iterations = c.weights.icp_point_to_plane_iterations;
  options.icp_stage_landmarks = c.weights.icp_stage_landmarks;
  options.landmark_stage = c.weights.landmark_stage;
  options.damped_step_trials = c.solver.damped_step_trials;
  options.predictor_warm_start = c.solver.predictor_warm_start;
  options.hold_clamped_tets = c.solver.hold_clamped_tets;
  options.icp_no_progress_iterations = c.stop.no_progress_iterations;
  options.eigenvalue_floor = c.solver.eigenvalue_floor;
  options.equilibrium.cholesky_method = c.solver.cholesky;
  options.woodbury.cholesky_method = c.solver.cholesky;
  if (auto error = options.validate()) throw tools::InputError(case_path + ": " + *error);

  // What a checkpoint must match to be resumed here: mode, mesh, markers, output surface, options.
  nlohmann::json identification;
  identification["mode"] = free_object ? "free" : "attached";
  // A free object's checkpointed state is in the template's frame since issue 18 (register_free
  // moves the scan onto the template); an older checkpoint's is in the scan's.
  if (free_object) identification["free_object_frame"] = "template";
  identification["tet_vertices"] = rest.rows();
  identification["tets"] = tets.rows();
  identification["mesh_hash"] = hex(hash_matrix(tets, hash_matrix(rest)));
  identification["attachments"] = constraints.attachments.size();
  identification["landmarks"] = constraints.landmarks.size();
  identification["icp_markers"] = constraints.icp_markers.size();
  {
    std::uint64_t h = hash_constraints(constraints.attachments, tools::kFnvOffset);
    h = hash_constraints(constraints.landmarks, h);
    for (const Eigen::Vector3d& z : constraints.icp_markers) h = hash_matrix(z, h);
    identification["markers_hash"] = hex(h);
  }
  identification["surface_hash"] =
      hex(hash_matrix(surface_triangles, hash_points(surface_points, tools::kFnvOffset)));
  identification["options"] = {{"alpha", tools::hex_double(options.alpha)},
                               {"beta", tools::hex_double(options.beta)},
                               {"attachment_stiffness", tools::hex_double(stiffness)},
                               {"max_iterations_per_stage", options.max_iterations_per_stage},
                               {"max_marker_error", tools::hex_double(options.max_marker_error)},
                               {"min_step", tools::hex_double(options.min_step)},
                               {"icp_stage_landmarks", options.icp_stage_landmarks},
                               {"landmark_stage", options.landmark_stage},
                               {"damped_step_trials", options.damped_step_trials},
                               {"predictor_warm_start", options.predictor_warm_start},
                               {"hold_clamped_tets", options.hold_clamped_tets},
                               {"icp_no_progress_iterations", options.icp_no_progress_iterations},
                               {"eigenvalue_floor", tools::hex_double(options.eigenvalue_floor)},
                               {"cholesky", offline::to_string(c.solver.cholesky)}};
  for (const double f : options.icp_weight_ramp) {
    identification["options"]["icp_weight_ramp"].push_back(tools::hex_double(f));
  }
  const Outputs out{fs::path(request.out_dir)};
  if (request.resume) {
    if (const auto mismatch =
            tools::identification_mismatch(request.resume->identification, identification)) {
      throw tools::InputError(out.checkpoint().string() + ": does not match " + case_path +
                              " as it is now (" + *mismatch +
                              "): the case, its template or its markers changed since the run "
                              "started; start it again with --case");
    }
    if (request.resume->state && request.resume->state->free_object != free_object) {
      throw tools::InputError(out.checkpoint().string() + ": its state is of a " +
                              (free_object ? "attached" : "free") + " object, the case's is not");
    }
  }

  // Every input is valid: only now does OUTDIR get created. Results of an earlier run there go
  // first, so that a run killed from now on leaves nothing that looks finished (report.json is
  // written last); the checkpoint marks the run as unfinished and resumable from the start.
  prepare_output_dir(out);
  for (const fs::path& stale :
       {out.report(), out.surface(), out.vtu(), out.dir / "result_surface.off",
        out.dir / "result_surface.stl", out.dir / "result_surface.ply",
        out.dir / "marker_errors.png", out.dir / "convergence.png"}) {
    std::error_code ec;
    fs::remove(stale, ec);
  }
  for (const std::string& transferred : c.transfer_paths) {
    const fs::path stale = out.dir / ("transfer_" + fs::path(transferred).filename().string());
    std::error_code ec;
    fs::remove(stale, ec);
  }
  {
    std::error_code ec;
    fs::remove_all(out.dir / "slices", ec);
  }
  tools::RegisterCheckpoint checkpoint;
  checkpoint.case_path = request.case_path;
  checkpoint.case_file = fs::absolute(request.case_file).string();
  checkpoint.truth_path = request.truth_path;
  checkpoint.truth_file =
      request.truth_file.empty() ? std::string() : fs::absolute(request.truth_file).string();
  checkpoint.max_iterations = max_iterations;
  checkpoint.identification = identification;
  if (request.resume) {
    checkpoint.resumes = request.resume->resumes + 1;
    checkpoint.state = request.resume->state;
  }
  tools::write_checkpoint(out.checkpoint(), checkpoint);
  const auto save_checkpoint = [&](const offline::GaussNewtonCheckpoint& state) {
    checkpoint.state = state;
    tools::write_checkpoint(out.checkpoint(), checkpoint);
  };
  const offline::GaussNewtonCheckpoint* resume_state =
      request.resume && request.resume->state ? &*request.resume->state : nullptr;

  // ---- registration
  start = Clock::now();
  log.line(
      "registering: {} tets, {} plastic dofs, alpha {:g}, beta {:g}, attachment stiffness "
      "{:g}, ICP tolerance {:.3g}{}",
      tets.rows(), 6 * tets.rows(), options.alpha, options.beta, stiffness, max_marker_error, u);
  // The stages as the registration runs them, for the estimate of the time left: the mean time
  // of a Gauss–Newton iteration so far times the iterations the stages may still take (an upper
  // bound: stages usually stop early).
  std::vector<offline::RegistrationStage> stages;
  if (!free_object) stages.push_back(offline::RegistrationStage::kAttachments);
  if (!constraints.landmarks.empty() &&
      (options.landmark_stage || constraints.icp_markers.empty() || !options.icp_stage_landmarks))
    stages.push_back(offline::RegistrationStage::kLandmarks);
  if (!constraints.icp_markers.empty()) stages.push_back(offline::RegistrationStage::kIcpMarkers);
  double iteration_seconds = 0.0;
  int iterations_timed = 0;
  const auto time_iteration = [&](const offline::GaussNewtonIteration& it) {
    if (it.stage == offline::RegistrationStage::kInitialFit) return;
    iteration_seconds += it.seconds;
    ++iterations_timed;
  };
  if (resume_state != nullptr) {
    for (const offline::GaussNewtonIteration& it : resume_state->iterations) time_iteration(it);
  }
  const auto progress = [&](const offline::GaussNewtonIteration& it) {
    time_iteration(it);
    std::string left;
    const auto at = std::find(stages.begin(), stages.end(), it.stage);
    if (iterations_timed > 0 && at != stages.end()) {
      const long remaining =
          std::max(0L, static_cast<long>(options.max_iterations_per_stage - it.iteration)) +
          static_cast<long>(options.max_iterations_per_stage) *
              static_cast<long>(stages.end() - at - 1);
      left = fmt::format("  at most {} left",
                         duration(remaining * iteration_seconds / iterations_timed));
    }
    log.line(
        "  {:<11} {:>3}  objective {:.4e}  step {:.3f}  marker error mean {:.4g} max {:.4g}{}"
        "  {:>2} solves  {:.1f} s{}",
        offline::to_string(it.stage), it.iteration, it.objective, it.step,
        it.marker_error_mean * frame.scale, it.marker_error_max * frame.scale, u,
        it.equilibrium_solves, it.seconds, left);
  };
  log.line("mode: {}", free_object ? "free object (no attachments: rigid frame fitted, §3.6)"
                                   : "attached object");
  if (request.resume) {
    if (resume_state == nullptr) {
      log.line(
          "resuming: the run stopped before its initial fit was done; registering from the "
          "start");
    } else if (resume_state->next_stage) {
      log.line("resuming at stage {} iteration {} ({} iterations done, {:.1f} s of registration)",
               offline::to_string(*resume_state->next_stage), resume_state->next_iteration,
               resume_state->iterations.size(), resume_state->seconds);
    } else {
      log.line("resuming after the last stage ({} iterations done): writing the outputs",
               resume_state->iterations.size());
    }
  }
  const offline::RegistrationResult result =
      free_object ? offline::register_free(*energy, constraints, closest.get(), options, progress,
                                           save_checkpoint, resume_state)
                  : offline::register_attached(*energy, constraints, closest.get(), options,
                                               progress, save_checkpoint, resume_state);
  const offline::GaussNewtonSummary& summary = result.summary;
  phases["registration"] = seconds_since(start);
  log.line("registration: {} ({}), final marker error mean {:.4g} max {:.4g}{}, {:.1f} s",
           offline::to_string(summary.termination), summary.message.empty() ? "-" : summary.message,
           summary.marker_error_mean * frame.scale, summary.marker_error_max * frame.scale, u,
           summary.seconds);

  // ---- outputs (each written atomically; the report last, so its presence means "done")
  start = Clock::now();
  nlohmann::json report;
  report["tool"] = "sinew-register";
  report["case"] = request.case_path;
  report["resumes"] = checkpoint.resumes;
  report["length_unit"] = unit.empty() ? "template units" : unit;
  report["inputs"] = inputs;
  report["mode"] = free_object ? "free" : "attached";
  report["options"] = {{"alpha", options.alpha},
                       {"beta", options.beta},
                       {"attachment_stiffness", stiffness},
                       {"max_iterations_per_stage", options.max_iterations_per_stage},
                       {"max_marker_error", max_marker_error},
                       {"min_step", options.min_step},
                       {"icp_weight_ramp", options.icp_weight_ramp},
                       {"icp_no_progress_iterations", options.icp_no_progress_iterations},
                       {"cholesky", offline::to_string(c.solver.cholesky)},
                       {"mesh_cell_size_fraction", c.mesh.cell_size_fraction}};
  nlohmann::json iterations = nlohmann::json::array();
  for (const offline::GaussNewtonIteration& it : summary.iterations) {
    iterations.push_back({{"stage", offline::to_string(it.stage)},
                          {"iteration", it.iteration},
                          {"objective", it.objective},
                          {"objective_before", it.objective_before},
                          {"step", it.step},
                          {"marker_error_mean", it.marker_error_mean * frame.scale},
                          {"marker_error_max", it.marker_error_max * frame.scale},
                          {"equilibrium_solves", it.equilibrium_solves},
                          {"predicted_decrease", it.predicted_decrease},
                          {"clamped_tets", it.clamped_tets},
                          {"damping", it.damping},
                          {"projected_search", it.projected_search},
                          {"jacobian_seconds", it.jacobian_seconds},
                          {"woodbury_seconds", it.woodbury_seconds},
                          {"line_search_seconds", it.line_search_seconds},
                          {"seconds", it.seconds}});
  }
  report["iterations"] = iterations;
  report["termination"] = offline::to_string(summary.termination);
  report["message"] = summary.message;
  report["usable"] = summary.usable();
  report["final"] = {
      {"stage", summary.iterations.empty() ? std::string("none")
                                           : offline::to_string(summary.iterations.back().stage)},
      {"objective", summary.final_objective},
      {"initial_objective", summary.initial_objective},
      {"marker_error_mean", summary.marker_error_mean * frame.scale},
      {"marker_error_max", summary.marker_error_max * frame.scale}};

  if (summary.usable() && !constraints.landmarks.empty()) {
    // The landmarks at the result (the ICP stage may or may not have kept them).
    double sum = 0.0, largest = 0.0;
    for (const offline::PointConstraint& pc : constraints.landmarks) {
      const double e =
          (offline::embedded_position(tets, pc.point, result.x) - pc.target).norm() * frame.scale;
      sum += e;
      largest = std::max(largest, e);
    }
    const double mean = sum / static_cast<double>(constraints.landmarks.size());
    report["final"]["landmark_error_mean"] = mean;
    report["final"]["landmark_error_max"] = largest;
    log.line("landmarks at the result: mean {:.4g} max {:.4g}{}", mean, largest, u);
  }

  nlohmann::json written = nlohmann::json::array();
  if (summary.usable()) {
    // Deformed surface.
    offline::io::SurfaceMesh deformed;
    if (c.template_is_tet_mesh) {
      deformed.vertices.resize(static_cast<Eigen::Index>(boundary_vertices.size()), 3);
      for (std::size_t i = 0; i < boundary_vertices.size(); ++i)
        deformed.vertices.row(static_cast<Eigen::Index>(i)) =
            result.x.segment<3>(3 * boundary_vertices[i]).transpose();
    } else {
      deformed.vertices.resize(static_cast<Eigen::Index>(surface_points.size()), 3);
      for (std::size_t i = 0; i < surface_points.size(); ++i)
        deformed.vertices.row(static_cast<Eigen::Index>(i)) =
            offline::embedded_position(tets, surface_points[i], result.x).transpose();
    }
    deformed.vertices = frame.to_user(deformed.vertices);
    deformed.triangles = surface_triangles;
    std::string error;
    if (!offline::io::write_obj(out.surface().string(), deformed, &error))
      throw std::runtime_error(error);
    written.push_back(out.surface().string());
    // Also in the template's own format, for the tools that read it.
    {
      std::string extension = fs::path(c.template_path).extension().string();
      for (char& ch : extension)
        ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
      if (!c.template_is_tet_mesh &&
          (extension == ".off" || extension == ".stl" || extension == ".ply")) {
        const fs::path same = out.dir / ("result_surface" + extension);
        if (!offline::io::write_surface_mesh(same.string(), deformed, &error))
          throw std::runtime_error(error);
        written.push_back(same.string());
      }
    }

    if (truth) {
      const tools::SurfaceDistanceStats to_truth =
          tools::vertex_to_surface_distances(deformed, *truth);
      const tools::SurfaceDistanceStats from_truth =
          tools::vertex_to_surface_distances(*truth, deformed);
      const double farthest = std::max(to_truth.max, from_truth.max);
      // The vertex means above weigh each surface by its mesh density; the peers' figure
      // (issue 18) is area-uniform: 30,000 samples on each surface, mean over both.
      const tools::SymmetricSurfaceDistance sampled =
          tools::sampled_surface_distance(deformed, *truth);
      report["truth"] = {{"surface", request.truth_path},
                         {"symmetric_mean_area_sampled", sampled.mean},
                         {"samples_per_surface", sampled.samples},
                         {"result_samples_to_truth_mean", sampled.a_to_b.mean},
                         {"result_samples_to_truth_max", sampled.a_to_b.max},
                         {"truth_samples_to_result_mean", sampled.b_to_a.mean},
                         {"truth_samples_to_result_max", sampled.b_to_a.max},
                         {"result_to_truth_mean", to_truth.mean},
                         {"result_to_truth_max", to_truth.max},
                         {"truth_to_result_mean", from_truth.mean},
                         {"truth_to_result_max", from_truth.max},
                         {"max_fraction_of_diagonal", farthest / frame.scale}};
      log.line(
          "truth: result vertices to {} mean {:.4g} max {:.4g}{}; its vertices to the result "
          "mean {:.4g} max {:.4g}{}; worst {:.2f}% of the diagonal",
          request.truth_path, to_truth.mean, to_truth.max, u, from_truth.mean, from_truth.max, u,
          100 * farthest / frame.scale);
      log.line(
          "truth: symmetric surface distance {:.4g}{} (mean over {} area-uniform samples on each "
          "surface: result to truth {:.4g}, truth to result {:.4g}{})",
          sampled.mean, u, sampled.samples, sampled.a_to_b.mean, sampled.b_to_a.mean, u);
    }

    // The deformed tet mesh, in the user's frame (result.vtu below).
    offline::TetMesh mesh;
    mesh.vertices = frame.to_user(positions(result.x));
    mesh.tets = tets;

    // Where the markers hold the surface and where the smoothness term alone shapes it.
    const offline::MarkerCoverage coverage =
        result_coverage(constraints, positions(result.x), boundary->triangles());
    {
      const double spacings = offline::MarkerCoverageOptions{}.uncovered_spacings;
      const Eigen::RowVector3d farthest = mesh.vertices.row(coverage.farthest_vertex);
      const Eigen::RowVector3d weakest = mesh.vertices.row(coverage.weakest_vertex);
      report["coverage"] = {
          {"nominal_spacing", coverage.nominal_spacing * frame.scale},
          {"uncovered_spacings", spacings},
          {"max_distance", coverage.max_distance * frame.scale},
          {"max_distance_spacings", coverage.max_distance / coverage.nominal_spacing},
          {"farthest_point", {farthest.x(), farthest.y(), farthest.z()}},
          {"uncovered_area_fraction", coverage.uncovered_area_fraction},
          {"pinning_threshold", coverage.pinning_threshold},
          {"min_pinning", coverage.min_pinning},
          {"weakest_point", {weakest.x(), weakest.y(), weakest.z()}},
          {"weakly_pinned_area_fraction", coverage.weakly_pinned_area_fraction}};
      log.line(
          "coverage: {:.1f}% of the surface is farther than {} marker spacings ({:.3g}{}) from "
          "every marker and attachment, {:.1f}% is held weakly along its normal (ICP markers hold "
          "the surface only along theirs); the weakest point is at ({:.4g}, {:.4g}, {:.4g}){}",
          100 * coverage.uncovered_area_fraction, spacings,
          spacings * coverage.nominal_spacing * frame.scale, u,
          100 * coverage.weakly_pinned_area_fraction, weakest.x(), weakest.y(), weakest.z(),
          coverage.weakly_pinned_area_fraction > 0 || coverage.uncovered_area_fraction > 0
              ? ". The shape there comes from the smoothness term, not from the data: result.vtu's "
                "marker_pinning and distance_to_nearest_marker show where markers would help"
              : "");
    }

    // Plastic field per tet.
    Eigen::MatrixXd Fp(tets.rows(), 9), stretches(tets.rows(), 3);
    Eigen::VectorXd det(tets.rows()), ratio(tets.rows());
    for (Eigen::Index t = 0; t < tets.rows(); ++t) {
      const Eigen::Matrix3d F = offline::plastic_strain_matrix(result.s.segment<6>(6 * t));
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) Fp(t, 3 * i + j) = F(i, j);
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(F, Eigen::EigenvaluesOnly);
      stretches.row(t) = eig.eigenvalues().transpose();
      ratio[t] = eig.eigenvalues().maxCoeff() / eig.eigenvalues().minCoeff();  // Fig. 1 e
      det[t] = F.determinant();
    }
    // Fig. 17: the tets' shape before (the template mesh) and after (deformed).
    offline::TetMesh rest_mesh;
    rest_mesh.vertices = frame.to_user(rest);
    rest_mesh.tets = tets;
    auto quality_json = [](const offline::TetMeshQuality& q) {
      return nlohmann::json{{"min_dihedral_degrees", q.min_dihedral_degrees},
                            {"max_dihedral_degrees", q.max_dihedral_degrees},
                            {"min_radius_ratio", q.min_radius_ratio},
                            {"mean_radius_ratio", q.mean_radius_ratio},
                            {"inverted_tets", q.inverted_tets}};
    };
    const offline::TetMeshQuality before = offline::tet_mesh_quality(rest_mesh);
    const offline::TetMeshQuality after = offline::tet_mesh_quality(mesh);
    report["mesh_quality"] = {{"template", quality_json(before)}, {"result", quality_json(after)}};
    log.line(
        "tet quality: smallest dihedral angle {:.1f} deg in the template, {:.1f} deg in the "
        "result ({} inverted tets)",
        before.min_dihedral_degrees, after.min_dihedral_degrees, after.inverted_tets);
    if (!offline::write_vtu_fields(
            out.vtu().string(), mesh,
            {{"det_Fp", det},
             {"Fp", Fp},
             {"principal_stretches", stretches},
             {"stretch_ratio", ratio}},
            {{"distance_to_nearest_marker", coverage.distance * frame.scale},
             {"marker_pinning", coverage.pinning / coverage.pinning_threshold}},
            &error))
      throw std::runtime_error(error);
    written.push_back(out.vtu().string());

    for (std::size_t k = 0; k < c.transfer_paths.size(); ++k) {
      const fs::path target =
          out.dir / ("transfer_" + fs::path(c.transfer_paths[k]).filename().string());
      tools::transfer_surface(c.transfer_paths[k], target.string(),
                              [&](const Eigen::Vector3d&, long index) -> Eigen::Vector3d {
                                const Eigen::Vector3d q = offline::embedded_position(
                                    tets, transfer_points[k][static_cast<std::size_t>(index)],
                                    result.x);
                                return frame.to_user(q.transpose()).row(0).transpose();
                              });
      written.push_back(target.string());
    }

    // Fig. 18: the result's cross-sections over the scan.
    if (scan_image) {
      tools::SlicePictureOptions slice_options;
      slice_options.count = c.scan_image->slices;
      slice_options.label = c.scan_image->label;
      slice_options.window_low = c.scan_image->window_low;
      slice_options.window_high = c.scan_image->window_high;
      nlohmann::json slices = nlohmann::json::array();
      for (const tools::SlicePicture& picture :
           tools::write_slice_pictures(*scan_image, scan_mask ? &*scan_mask : nullptr, deformed,
                                       (out.dir / "slices").string(), slice_options)) {
        nlohmann::json entry = {{"file", picture.file}, {"k", picture.k}};
        if (picture.mean_distance) {
          entry["mean_distance_to_mask_outline"] = *picture.mean_distance;
          log.line("slice k = {}: cross-section {:.3g} {} from the mask's outline on average",
                   picture.k, *picture.mean_distance, unit.empty() ? "units" : unit);
        }
        slices.push_back(entry);
        written.push_back(picture.file);
      }
      report["slices"] = slices;
    }

    // Figs. 16 and 9: the final marker errors' histogram and the convergence plot.
    std::vector<double> marker_errors;
    if (!constraints.icp_markers.empty()) {
      closest->update(result.x);
      for (const Eigen::Vector3d& z : constraints.icp_markers) {
        const Eigen::Vector3d p = offline::embedded_position(tets, closest->closest(z), result.x);
        marker_errors.push_back((p - z).norm() * frame.scale);
      }
    } else {
      const auto& list =
          constraints.landmarks.empty() ? constraints.attachments : constraints.landmarks;
      for (const offline::PointConstraint& pc : list) {
        marker_errors.push_back(
            (offline::embedded_position(tets, pc.point, result.x) - pc.target).norm() *
            frame.scale);
      }
    }
    const fs::path histogram = out.dir / "marker_errors.png",
                   convergence = out.dir / "convergence.png";
    const std::string unit_name = unit.empty() ? "template units" : unit;
    if (!tools::write_error_histogram_png(histogram.string(), marker_errors, unit_name, &error) ||
        !tools::write_convergence_png(convergence.string(), summary.iterations, frame.scale,
                                      unit_name, &error)) {
      throw std::runtime_error(error);
    }
    written.push_back(histogram.string());
    written.push_back(convergence.string());
  }
  phases["writing"] = seconds_since(start);
  report["outputs"] = written;
  report["totals"] = {{"iterations", summary.iterations.size()},
                      {"equilibrium_solves", summary.equilibrium_solves},
                      {"registration_seconds", summary.seconds},
                      {"seconds", seconds_since(run_start)},
                      {"phases", phases}};
  tools::write_json_file(out.report().string(), report);
  written.push_back(out.report().string());
  {
    // Done: nothing left to resume.
    std::error_code ec;
    fs::remove(out.checkpoint(), ec);
  }
  for (const auto& path : written) log.line("wrote {}", path.get<std::string>());
  return summary.usable() ? 0 : 1;
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
      if (!quiet) {
        fmt::print(
            "wrote {}/case.json: a {:g} x {:g} x {:g} mm capsule ({} vertices) attached at its x = "
            "0 end by {} points; {} ICP markers on its known deformation (free part {:g}x longer, "
            "bent {:.0f} degrees; vertices move up to {:.1f} mm), {}/truth_surface.obj\n",
            demo_dir, demo.options.shape.length, 2 * demo.options.shape.radius_y,
            2 * demo.options.shape.radius_z, demo.template_surface.vertices.rows(),
            demo.attachment_points.rows(), demo.markers.rows(), 1 + demo.options.stretch,
            demo.options.bend_radians * 180 / std::acos(-1.0), demo.max_displacement, demo_dir);
      }
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
