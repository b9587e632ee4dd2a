#pragma once
/// One call that registers a case (seed 003, Wang, Matcuk & Barbič): everything sinew-register does
/// between reading the case file and writing its outputs. The template is read (surface or tet
/// mesh), normalised (bounding-box centre at the origin, diagonal 1, unit material), tet-meshed
/// (surface templates), the attachments, landmarks, template surface vertices and transferred
/// surfaces are embedded in the tets, the staged Gauss–Newton registration runs
/// (offline::register_attached, or offline::register_free when there are no attachments), and the
/// result is returned in the case's units with the figures of the report: marker and landmark
/// errors, tet quality before and after, marker coverage and the per-tet plastic field.
///
/// Files: the template and the transferred surfaces named by the case are read; nothing is
/// written (tools/register writes OBJ/PLY/VTU, PNG and report.json from the result).
///
///   offline::RegistrationCase c = ...;           // or tools::read_registration_case(path)
///   offline::RegisterCaseResult r = offline::register_case(c, {});
///   if (r.shape) use(r.shape->surface);          // the deformed template surface, case units

#include <Eigen/Core>
#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "offline/io/surface_mesh_io.hpp"
#include "offline/io/tet_mesh_io.hpp"
#include "offline/meshing/tet_mesher.hpp"
#include "offline/registration/gauss_newton.hpp"
#include "offline/registration/marker_coverage.hpp"
#include "offline/registration/registration_case.hpp"

namespace sinew::offline {

/// The case's frame → the normalised one: x_normalised = (x − centre) / scale.
struct CaseNormalisation {
  Eigen::RowVector3d centre = Eigen::RowVector3d::Zero();
  double scale = 1.0;  ///< the template's bounding-box diagonal, case units
  /// Rounded to multiples of 2⁻⁴⁰ (1e-12 of the diagonal) so that the same case in millimetres and
  /// in metres gives bitwise the same normalised input, hence the same tet mesh (CGAL's
  /// refinement is not continuous in its input).
  Eigen::MatrixXd to_frame(const Eigen::MatrixXd& points) const;
  /// The scan's points of a free object are not rounded here: register_free moves them onto the
  /// template and rounds them there. Rounded in the scan's own frame, the same points in another
  /// pose of the scan differ by up to half a step (5e-13) after that move and cross register_free's
  /// grid far more often (with a 2⁻³⁰ grid there, sub-verse013 rotated by 180° became another run,
  /// 7e-3 of the diagonal away).
  Eigen::MatrixXd scan_to_frame(const Eigen::MatrixXd& points, bool free_object) const;
  /// Normalised → case units (#P by 3).
  Eigen::MatrixXd to_user(const Eigen::MatrixXd& points) const;
};

struct RegisterCaseOptions {
  /// Overrides the case's stop.max_iterations_per_stage (sinew-register --max-iterations).
  std::optional<int> max_iterations;
  /// Continue a checkpointed run from this state (offline::register_attached's resume); must
  /// outlive the call. nullptr: from the start.
  const GaussNewtonCheckpoint* resume = nullptr;
  /// The run continues an interrupted one (messages say so; resume may still be nullptr when it
  /// stopped before its initial fit).
  bool resuming = false;
};

/// The registration problem as set up, in the normalised frame: what a checkpoint of the run
/// identifies (tools/register/checkpoint_file.hpp) and what the result figures are computed on.
struct PreparedCase {
  bool free_object = false;  ///< no attachments: register_free (seed 003 §3.6)
  CaseNormalisation frame;
  Eigen::MatrixXd rest;     ///< #V by 3 tet mesh vertices, normalised
  common::TetIndices tets;  ///< #T by 4
  RegistrationConstraints constraints;
  /// The output surface: template surface vertices as material points (surface templates; empty
  /// for a tet-mesh template, whose output surface is its boundary) and its triangles.
  std::vector<EmbeddedPoint> surface_points;
  Eigen::MatrixXi surface_triangles;
  std::vector<int> boundary_vertices;  ///< tet-mesh template: mesh vertex of each output vertex
  GaussNewtonOptions options;
  double attachment_stiffness = 0.0;      ///< μ·diagonal
  double max_marker_error = 0.0;          ///< ICP tolerance, case units
  std::vector<RegistrationStage> stages;  ///< as the registration runs them
};

/// Callbacks of register_case; each may be empty.
struct RegisterCaseHooks {
  /// One line of progress for a person (no trailing newline): what was read, meshed, embedded, one
  /// line per Gauss–Newton iteration with an estimate of the time left, the figures.
  std::function<void(const std::string&)> message;
  /// After every input check, before the registration starts: the place to check a checkpoint
  /// against the problem and to create output folders. May throw to stop the run.
  std::function<void(const PreparedCase&)> prepared;
  /// After every Gauss–Newton iteration (offline::GaussNewtonProgress).
  GaussNewtonProgress iteration;
  /// The state after every iteration, to resume from (offline::GaussNewtonCheckpointCallback).
  GaussNewtonCheckpointCallback checkpoint;
};

/// What was read and set up (sinew-register's report.json "inputs"); lengths in case units.
struct CaseInputSummary {
  Eigen::Index template_vertices = 0;
  std::optional<Eigen::Index> template_triangles;  ///< surface templates
  double bounding_box_diagonal = 0.0;
  std::optional<TetMesherSummary> mesher;  ///< surface templates
  Eigen::Index tet_vertices = 0;
  Eigen::Index tets = 0;
  /// Farthest attachment or landmark template point outside the tet mesh.
  double embedding_max_distance = 0.0;
  /// Farthest template surface vertex outside the tet mesh.
  double surface_embedding_max_distance = 0.0;
};

/// Mean and largest of a set of distances, case units.
struct ErrorStats {
  double mean = 0.0;
  double max = 0.0;
};

/// The registered shape and its figures (a usable registration only); lengths in case units.
struct RegisteredShape {
  io::SurfaceMesh surface;  ///< the deformed output surface (PreparedCase::surface_triangles)
  TetMesh mesh;             ///< the deformed tet mesh
  TetMesh rest_mesh;        ///< the template tet mesh
  /// Where the markers hold the surface (offline/registration/marker_coverage.hpp), in the
  /// normalised frame.
  MarkerCoverage coverage;
  /// Per tet: Fp row-major (#T by 9), its eigenvalues ascending (#T by 3), their ratio largest /
  /// smallest (seed 003 Fig. 1 e) and det Fp.
  Eigen::MatrixXd Fp, principal_stretches;
  Eigen::VectorXd stretch_ratio, det_Fp;
  TetMeshQuality template_quality, result_quality;  ///< seed 003 Fig. 17
  /// Final marker errors (Fig. 16): ICP markers to their closest points, else the landmarks, else
  /// the attachments.
  std::vector<double> marker_errors;
  /// Per transferred surface of the case: the deformed position of every vertex (#V by 3).
  std::vector<Eigen::MatrixXd> transferred;
};

/// Seconds per phase of register_case.
struct CasePhaseSeconds {
  double reading = 0.0;
  double meshing = 0.0;
  double embedding = 0.0;
  double registration = 0.0;
  double figures = 0.0;
};

struct RegisterCaseResult {
  PreparedCase problem;
  CaseInputSummary inputs;
  /// The registration's result (x, s in the normalised frame) and summary (marker errors in
  /// diagonals: multiply by problem.frame.scale).
  RegistrationResult registration;
  /// The landmarks at the result (a usable registration with landmarks).
  std::optional<ErrorStats> landmark_errors;
  std::optional<RegisteredShape> shape;  ///< a usable registration only
  CasePhaseSeconds seconds;
};

/// Registers case c (see the top of this header). Throws RegistrationInputError with one line
/// naming the file or field for an input it cannot use (unreadable template, marker points far
/// from it, a template that cannot be meshed, too few markers for a free object, invalid
/// options); a registration that fails numerically is a termination value in
/// result.registration.summary, not an exception.
RegisterCaseResult register_case(const RegistrationCase& c, const RegisterCaseOptions& options,
                                 const RegisterCaseHooks& hooks = {});

/// Distances between a registered surface and a known one (sinew-register --truth), same units.
struct TruthDistances {
  ErrorStats result_to_truth;  ///< result vertices to the truth surface
  ErrorStats truth_to_result;  ///< truth vertices to the result surface
  /// Area-uniform samples (offline/registration/surface_distance.hpp sampled_surface_distance).
  ErrorStats result_samples_to_truth, truth_samples_to_result;
  double symmetric_mean_area_sampled = 0.0;
  int samples_per_surface = 0;
};
TruthDistances truth_distances(const io::SurfaceMesh& result, const io::SurfaceMesh& truth);

}  // namespace sinew::offline
