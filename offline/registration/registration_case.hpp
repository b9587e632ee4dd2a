#pragma once
/// What sinew-register registers, as typed structs (seed 003: a template organ, its attachments,
/// landmarks and ICP markers, and the options of the run). tools/register/case_file.hpp fills it
/// from a case file and documents that schema; a C++ program can fill it directly and call
/// offline::register_case (offline/registration/register_case.hpp).
///
/// Normalised frame: register_case translates the template's bounding-box centre to the origin
/// and scales its diagonal to 1, with a unit material (μ = 1, ν = 0.4). alpha weighs the squared
/// marker misfit (in diagonals²) against the dimensionless plastic-strain smoothness ½‖L s‖², beta
/// the attachment misfit; attachment_stiffness is the spring constant of each attachment in units
/// of μ·diagonal (appendix G: scaling the stiffness is equivalent to scaling the weights). The same
/// numbers therefore suit a liver in millimetres and a bar in metres.

#include <Eigen/Core>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "offline/linalg/sparse_cholesky.hpp"
#include "offline/meshing/tet_mesher.hpp"

namespace sinew::offline {

/// An input the registration cannot use (a point far from the template, a template that cannot
/// be meshed, invalid options): what() is one line naming the file or field.
class RegistrationInputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class LengthUnit {
  kUnspecified,  ///< no "units" key: lengths are reported in the template's units
  kMillimetre,
  kMetre,
};

/// "mm", "m" or "" (unspecified).
const char* to_string(LengthUnit unit);

/// Corresponding points in the case's units: template_points.row(i) is a material point of the
/// template (on or near it) that should move to target_points.row(i).
struct PointPairSet {
  Eigen::MatrixXd template_points;  ///< #P by 3
  Eigen::MatrixXd target_points;    ///< #P by 3
  std::vector<std::string> labels;  ///< one per pair (maybe ""), or empty
  /// Where they came from, for messages: the case file (points given inline) or the marker
  /// file's path (of the targets, for a {"template": FILE, "target": FILE} pair of lists).
  std::string source;
  /// As source, for the template points (differs for a pair of lists only).
  std::string template_source;
  Eigen::Index size() const { return template_points.rows(); }
};

/// The ICP weight ramp of a case that does not give one (RegistrationWeights::icp_weight_ramp).
/// Without landmarks: 1e-3, 1e-2, 1e-1 of alpha, three iterations each (9). With landmarks: every
/// decade from 1e-7 to 1e-1, three iterations each (21; register_case passes landmarks = the case
/// has landmarks and keeps them in the ICP stage): at 1e-7·alpha the markers barely weigh
/// against the plastic strain's smoothness, so the first steps move only the smoothest fields
/// while the closest points settle, and each decade lets finer detail in. That needs the
/// extremities held: ICP markers pull a surface that falls short of them but not one that runs
/// past them (their closest points then lie on its sides), so a smooth field grows the ends of
/// an object whose ends only markers define. Measured (docs/registration.md "A ramp from 1e-7"):
/// the shared vertebrae (10 landmarks at the processes' tips) 0.756 / 0.541 / 0.569 → 0.597 /
/// 0.487 / 0.555 mm mean symmetric surface distance; the gluteus medius without landmarks 0.67
/// → 1.32 mm forward (its ends 4-6 mm past the markers), with two landmarks at its ends 0.74 →
/// 0.75 mm.
std::vector<double> default_icp_weight_ramp(bool landmarks);

struct RegistrationWeights {
  double alpha = 1e5;  ///< landmarks and ICP markers, per diagonal² of misfit; > 0
  /// Attachments in the objective, per diagonal²; ≥ 0. Default: 1e4 when attachments are the
  /// only observations; 0 with landmarks or ICP markers, where the stiff springs already meet the
  /// attachments and an attachment-only stage would only undo the constant initial fit (its
  /// Gauss–Newton step moves the uniform plastic modes the springs hardly see).
  std::optional<double> beta;
  double attachment_stiffness = 10;  ///< spring of each attachment, μ·diagonal; > 0
  /// ICP continuation (GaussNewtonOptions::icp_weight_ramp): factors of alpha for the
  /// first ICP iterations, each in (0, 1]. std::nullopt (the default):
  /// default_icp_weight_ramp(whether the case has landmarks).
  std::optional<std::vector<double>> icp_weight_ramp;
  /// ICP iterations whose markers count point to plane before point to point
  /// (GaussNewtonOptions::icp_point_to_plane_iterations); ≥ 0. Default 10 (measured:
  /// femur pair 0.391 → 0.335 mm mean symmetric distance; gluteus medius 2.04 / 0.73 → 0.73 /
  /// 0.58 mm, worst 13.6 → 5.6 mm).
  int icp_point_to_plane_iterations = 10;
  /// Landmarks stay in the ICP stage's objective (GaussNewtonOptions::
  /// icp_stage_landmarks); default true: the user's correspondences are met in the result too.
  bool icp_stage_landmarks = true;
  /// GaussNewtonOptions::landmark_stage: with landmarks in the ICP stage and ICP
  /// markers, the separate landmark stage runs only when this is true; default false.
  bool landmark_stage = false;
};

struct RegistrationStop {
  /// ≥ 0. 40: the ICP stage's ramp takes the first 9 or 21 (default_icp_weight_ramp), and the
  /// vertebrae meet their markers within 2-6 more.
  int max_iterations_per_stage = 40;
  /// ICP stop tolerance in the case's units; std::nullopt: 0.1% of the template's diagonal.
  std::optional<double> max_marker_error;
  double min_step = 0.01;  ///< in [0, 1)
  /// GaussNewtonOptions::icp_no_progress_iterations ("stop": {"no_progress_iterations":
  /// N}): the ICP stage also ends (small-decrease) once Φ after N iterations in a row is no lower
  /// than after an earlier one; ≥ 0, 0: off. Default 3 (see docs/registration.md).
  int no_progress_iterations = 3;
};

/// The mesher's options for a registration template: cells of 0.08 of the diagonal (a night's
/// run at most) and thin parts 4 tets across, so that a bend can vary the plastic strain across
/// them (a vertebra's processes; docs/registration.md, "Real bones": 3 and 5 were measured too).
TetMesherOptions registration_mesh_options();

struct RegistrationCase {
  std::string case_path;      ///< as given on the command line
  std::string template_path;  ///< resolved against the case file's folder
  bool template_is_tet_mesh = false;
  LengthUnit units = LengthUnit::kUnspecified;
  struct Solver {
    /// GaussNewtonOptions::damped_step_trials ("solver": {"damped_step_trials": N}).
    /// Default 4 (μ up to 1e3 of the smoothness term): real bones' ICP steps stall without it.
    int damped_step_trials = 4;
    /// GaussNewtonOptions::predictor_warm_start; default true.
    bool predictor_warm_start = true;
    /// GaussNewtonOptions::hold_clamped_tets ("solver": {"hold_clamped_tets": B}).
    /// Default true, with the thickness-sized mesh and the no-progress stop (the three together
    /// end every real case's ICP stage by the marker tolerance).
    bool hold_clamped_tets = true;
    /// GaussNewtonOptions::eigenvalue_floor; default 0.2 (the paper: 0.01): with a lower
    /// floor real bones meet their markers by squashing tets and the ICP stage stalls.
    double eigenvalue_floor = 0.2;
    /// GaussNewtonOptions::constant_strain_step_limit ("solver": {"constant_strain_step_limit":
    /// F}) and inverted_equilibrium_fallback ({"inverted_equilibrium_fallback": B}), both acting
    /// on directions damped at μ ≥ rescue_min_damping ({"rescue_min_damping": F}); defaults 0.5,
    /// true, 1e3 (GaussNewtonOptions: off). The bunny bulged 2x and bent 90° (attached) converge
    /// where they stall without them (the bent one with the held tets eliminated,
    /// GaussNewtonOptions::held_penalty_max_bytes: 2.3 GB where penalty rows were killed at
    /// 22 GB), and every other row rerun is byte-identical (issue 51, docs/registration.md
    /// "Default-safe", "Held tets without rows").
    double constant_strain_step_limit = 0.5;
    bool inverted_equilibrium_fallback = true;
    double rescue_min_damping = 1e3;
    /// Sparse Cholesky method of every factorisation ("solver": {"cholesky": "auto" |
    /// "simplicial" | "supernodal"}; SparseCholeskyMethod). Simplicial has no BLAS, so
    /// the run is the same with every OpenBLAS kernel and thread count (tests/tools/
    /// register_stability_sweep.sh); supernodal is much faster on large meshes but its result
    /// depends on the CPU's BLAS kernels. Default auto: simplicial up to 1e6 nonzeros in the
    /// factor (meshes up to about 8k tets), supernodal above; "simplicial" makes a large mesh
    /// reproducible too, at several times the factorisation time.
    SparseCholeskyMethod cholesky = SparseCholeskyMethod::kAuto;
  } solver;
  /// How a surface template is tet-meshed ("mesh" in a case file overrides these):
  /// registration_mesh_options(), a little coarser than the mesher's general default and sized
  /// by the local thickness.
  TetMesherOptions mesh = registration_mesh_options();
  bool mesh_options_given = false;
  PointPairSet attachments;
  PointPairSet landmarks;          ///< empty when absent
  Eigen::MatrixXd icp_markers;     ///< #M by 3 (0 rows when absent)
  std::string icp_markers_source;  ///< as PointPairSet::source
  /// Surfaces in the template's frame carried along by the deformation (seed 003 §4.3, the
  /// textured liver): written as OUTDIR/transfer_<name> (offline/registration/transfer.hpp).
  std::vector<std::string> transfer_paths;
  /// "scan_image": OUTDIR/slices/slice_kNNN.png of the result's cross-sections (seed 003 Fig. 18,
  /// tools/label/slice_pictures.hpp).
  struct ScanImage {
    std::string image;  ///< resolved path
    std::string mask;   ///< resolved path, empty when none
    int label = -1;
    int slices = 6;
    double window_low = -160, window_high = 240;
  };
  std::optional<ScanImage> scan_image;
  std::string coordinate_system;   ///< "RAS"/"LPS" when a marker file said so, else ""
  std::vector<std::string> notes;  ///< things the user should know (conversions, skipped points)
  RegistrationWeights weights;
  RegistrationStop stop;
};

}  // namespace sinew::offline
