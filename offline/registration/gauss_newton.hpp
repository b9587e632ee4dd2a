#pragma once
/// Plastic-strain registration of attached objects (seed 003, §3.3–3.4): find the plastic state s
/// (6m) and its static equilibrium x (3n) minimising eq. 6,
///   Φ(s, x) = ½‖L s‖² + Σ_k c_k/2 ‖A_k x + b_k‖²,   s.t. f_net(s, x) = f_e + f_a = 0 (eq. 7),
/// by the paper's Gauss–Newton method:
///  - per iteration, Z = −[√c_k A_k]·(∂f_net/∂x)⁻¹·∂f_net/∂s (eq. 12) from one
///  multi-right-hand-side
///    CHOLMOD solve with the tangent stiffness (J is never formed);
///  - the step Δs solves H Δs = −(L²s + Zᵀr), H = L² + ZᵀZ (eq. 11), by the Woodbury identity
///    (eqs. 13–14, offline/linalg/woodbury_solver.hpp);
///  - Fp(s + Δs) is kept positive definite by clamping its eigenvalues at 0.01 (§3.4);
///  - a line search over η ∈ [0, max_step] minimises Φ(s + ηΔs, x(η)), where every trial solves the
///    equilibrium warm-started from the current x and a failed equilibrium scores +∞. The 1D
///    minimiser is Brent's (golden section + parabolic interpolation), as in the paper;
///  - initial guess: one constant s for all tets fitted first (NLopt BOBYQA over its 6 entries);
///  - stages attachments → landmarks → ICP markers (§3.4): the output is computed with ICP markers
///    only when there are any; closest points are recomputed before every ICP iteration, their
///    barycentric coordinates frozen within it;
///  - a stage stops on its iteration limit, on η below min_step, when the relative decrease of Φ is
///    negligible, or (ICP stage) when the largest marker error is below max_marker_error.
///
/// Objective weights: attachments enter Φ with c_k = β (beta), landmarks and ICP markers with
/// c_k = α·weight_k (alpha); the attachment springs of f_net keep their own stiffness (the
/// PointConstraint::weight of each attachment), see §3.3.
///
/// Units: SI or any consistent system; the tools normalise the geometry first.
#include <Eigen/Core>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "offline/constraints/constraints.hpp"
#include "offline/equilibrium/equilibrium.hpp"
#include "offline/linalg/singular_solver.hpp"
#include "offline/linalg/sparse_cholesky.hpp"
#include "offline/linalg/woodbury_solver.hpp"
#include "offline/plastic/plastic_elastic_energy.hpp"
#include "offline/registration/closest_point.hpp"
#include "offline/registration/line_search.hpp"
#include "offline/rigid/rigid_stabilisation.hpp"

namespace sinew::offline {

enum class RegistrationStage {
  kInitialFit,   ///< the constant-s initial guess
  kAttachments,  ///< attachments only
  kLandmarks,    ///< attachments + landmarks
  kIcpMarkers,   ///< attachments + ICP markers (landmarks off)
};
const char* to_string(RegistrationStage stage);

struct GaussNewtonOptions {
  /// Objective weight α of landmarks and ICP markers (eq. 3), per metre² of misfit, against the
  /// dimensionless smoothness ½‖L s‖²; > 0. The paper used 1e9 on its meshes; on a 432-tet bar
  /// (tests/offline/test_gauss_newton.cpp) 1e9 over-fits the landmarks with a rough field
  /// (surface error 20% of the diagonal) while 1e3…1e7 all give 3–4%: 1e7 meets markers to ≲1 µm
  /// per 10 cm and stays smooth.
  double alpha = 1e7;
  /// Objective weight β of the attachment energy (eq. 3); ≥ 0. The paper: α/10.
  double beta = 1e6;
  /// Gauss–Newton iterations per stage (the paper: typically 20, up to 80); ≥ 0.
  int max_iterations_per_stage = 20;
  /// ICP stage: stop when every marker is this close to the surface (metres; the paper: 1 mm for
  /// hand muscles); ≥ 0 (0 disables). A landmark stage followed by an ICP stage stops when every
  /// landmark is this close to its target.
  double max_marker_error = 0.0;
  /// ICP-stage continuation: in the stage's iteration i ≤ icp_weight_ramp.size() the ICP markers
  /// weigh alpha·icp_weight_ramp[i − 1], then alpha. Weak markers first let the plastic-strain
  /// smoothness shape the surface while the closest points settle; met exactly at once, the
  /// first closest points (taken on a surface still millimetres off) are frozen in as slid
  /// correspondences (the stiffness annealing of non-rigid ICP). The stage's stopping tests
  /// (marker tolerance, small step, small decrease, a failed line search) apply from the first
  /// full-weight iteration on; the ramp's iterations count towards max_iterations_per_stage.
  /// Factors in (0, 1]; empty (the default): the paper's plain ICP stage. On the femur pair
  /// (tests/tools/test_register_femur.cpp) {1e-3 ×3, 1e-2 ×3, 1e-1 ×3} takes the mean symmetric
  /// surface distance from 0.57 to 0.41 mm.
  std::vector<double> icp_weight_ramp;
  /// ICP-stage continuation: in the stage's first icp_point_to_plane_iterations iterations the
  /// markers count point to plane, only their offset along the surface normal at the closest point
  /// (PointConstraint::plane_normal), so a marker no longer pins the material point it first
  /// landed on and the surface slides under it towards the smoother plastic field; the iterations
  /// after it are the paper's point to point (appendix F), which meets the markers. The stopping
  /// tests wait for them, as for icp_weight_ramp (both may be given: each counts from the
  /// stage's first iteration). ≥ 0; 0 (the default): point to point throughout.
  int icp_point_to_plane_iterations = 0;
  /// Keep the landmarks in the ICP stage's objective (weight alpha, as in the landmark stage).
  /// The paper (§3.4) drops them there: landmarks only guide the optimiser and the output is the
  /// ICP markers' alone. With closest-point markers only, a thin part of a real shape can slide
  /// along the markers and take the landmarks with it (the three vertebrae of ../shared/data/
  /// vertebrae end their ICP stage with the landmarks millimetres off); with them kept, the
  /// anatomical correspondence the user gave holds the surface in place and both sets are met.
  /// They follow the stage's weight ramp (icp_weight_ramp) like the markers. false (the
  /// default): the paper's ICP stage.
  bool icp_stage_landmarks = false;
  /// Run the landmark stage (§3.4) before the ICP stage. Only consulted when icp_stage_landmarks
  /// is on and there are ICP markers (the ICP stage then fits the landmarks itself): false skips
  /// it. On the vertebrae the landmark stage, ten landmarks met alone, left the ICP markers
  /// 2.6-6.2 mm off on average (20 mm at worst) where the constant initial fit had them at
  /// 0.9-1.8 mm: the plastic field between ten points is whatever is smoothest for them.
  bool landmark_stage = true;
  /// A stage stops when the line search's best η is below this (the paper uses 0.01); in [0, 1).
  double min_step = 0.01;
  /// Largest η tried by the line search; η = 1 is the full Gauss–Newton step. In (0, 4].
  double max_step = 1.0;
  /// A stage stops when Φ decreased by less than this fraction in an iteration; in [0, 1).
  double relative_decrease_tolerance = 1e-6;
  /// ICP stage, after its ramp and point-to-plane phase: also stop (kSmallDecrease) when Φ after
  /// the last icp_no_progress_iterations iterations is no lower than the stage's best Φ after an
  /// earlier iteration (by relative_decrease_tolerance), i.e. when the ICP alternation as a whole
  /// (step, rigid re-fit, fresh closest points) no longer lowers the objective. The in-iteration
  /// test compares Φ under one iteration's frozen closest points only: on sub-verse013 every
  /// iteration lowered that by 7-13% while the next iteration's fresh closest points raised it
  /// again, and the stage ran to its iteration limit. ≥ 0; 0 (the default): the in-iteration test
  /// alone.
  int icp_no_progress_iterations = 0;
  /// The full step η = 1 is accepted without a Brent search when Φ decreased by at least this
  /// fraction of the Gauss–Newton model's predicted decrease (and no Fp was clamped); in [0, 1],
  /// 0 always searches (the paper's plain Brent). Each search costs ~7 more equilibrium solves:
  /// at 30k tets that is 20 of a 43 s iteration.
  double full_step_acceptance = 0.5;
  /// Brent line search: evaluations (equilibrium solves) per iteration, ≥ 3; and the tolerance
  /// on η, in (0, 0.5).
  int line_search_evaluations = 12;
  double line_search_tolerance = 0.02;
  /// Fit one constant s to all tets before the Gauss–Newton stages (§3.4 "Initial guess").
  bool initial_constant_fit = true;
  /// Objective evaluations (equilibrium solves) of the constant fit, ≥ 10.
  int initial_fit_evaluations = 80;
  /// When the template's first equilibrium under the attachments cannot be solved directly, the
  /// attachment targets are moved there in this many equal load steps; ≥ 1 (1: no continuation).
  int first_equilibrium_steps = 16;
  /// Levenberg damping of the six constant-strain modes (the nullspace of L), relative to
  /// ‖ZΨ‖²/6, the constraints' own curvature along them; ≥ 0. H = L² + ZᵀZ is singular there when
  /// the stage's constraints hardly see a uniform change of s (stiff attachments alone), and
  /// δ = damping·‖ZΨ‖²/6 + 1e-12 keeps the Woodbury capacitance invertible (see
  /// WoodburySolver::set_constraint_rows_transposed).
  double nullspace_damping = 1e-6;
  /// In the attachments-only stage, a floor of that damping relative to ‖Z‖²_F/6, the
  /// constraints' total curvature; ≥ 0. Attachments alone hardly see a uniform strain, and without
  /// a floor that stage steps freely along it and undoes the constant initial fit (tests/offline/
  /// test_paper_figures.cpp: the Fig. 4 beam collapsed to 0.22x its width). Not applied in the
  /// landmark and ICP stages, whose markers do see uniform strains (a floor of 1e-2 there slowed
  /// the landmark ground-truth case from 0.7% to 7.9% surface error in 20 iterations).
  double attachment_stage_damping_floor = 0.1;
  /// Eigenvalue floor of Fp after each step (§3.4: 0.01); > 0.
  double eigenvalue_floor = kDefaultEigenvalueFloor;
  /// The line search runs along clamp(s + d) − s, the Gauss–Newton step d with the floor applied
  /// to its full step. When many tets hit the floor that path can climb at every η; then (no η
  /// decreased Φ and some tet was clamped) a second Brent search runs along the projected path
  /// s(η) = clamp(s + η·d), which follows d itself for small η. Fig. 4 beam at 5,184 tets, first
  /// point-to-plane ICP iteration: 1,412 tets clamped and Φ rose at every η of the first path;
  /// without the fallback the stage ended 7.9 mm off its markers (7.6% of the diagonal off the
  /// target), with it the markers are met to 0.5 µm (1.95%). false: the first search only.
  bool projected_search_fallback = true;
  /// Levenberg–Marquardt damping in the smoothness metric: when the full Gauss–Newton step is not
  /// taken as is (it clamped some tet's Fp, or Φ fell by less than full_step_acceptance of the
  /// model's decrease), up to this many more directions are tried, each solving
  ///   ((1 + μ)L² + ZᵀZ) Δs = −(L²s + Zᵀr)
  /// (the same Woodbury solve with Z/√(1+μ)), μ = damping_start, then ×damping_growth, and the
  /// first whose full step passes that test is taken. The next iteration starts from the μ taken
  /// divided by damping_growth (below damping_start: 0), so the damping follows the problem, as a
  /// trust region would; μ is kept in the iteration records (so a resumed run damps the same).
  /// When no trial passes, the line search runs along the last (most damped) direction. On real
  /// shapes (the vertebrae of ../shared/data/vertebrae) the undamped ICP steps push 10–18% of the
  /// tets below the Fp floor and the searches end at η ≈ 0.1 or fail; L² damping keeps the step
  /// smooth where the markers do not see it. 0 (the default): the plain step and search.
  int damped_step_trials = 0;
  /// Start each line-search equilibrium at the linear prediction x + η·(∂x/∂s)Δs (one more
  /// back-substitution per direction) instead of at x; when that solve fails, it is retried from
  /// x. false (the default): from x, as the paper. On the vertebrae the first ICP steps' solves
  /// failed from x for every damping up to 100.
  bool predictor_warm_start = false;
  /// When a step clamps tets at the eigenvalue floor, solve for the step again with those tets'
  /// plastic state held (six penalty rows each in Z, 1e3 times its largest row norm: an active
  /// set), and search along that step; not in the ICP stage's ramp and point-to-plane phase,
  /// where 100-240 tets clamp per step and the extra rows made a Woodbury solve take up to 34 s.
  /// The clamped step of the coupled system (L² links neighbouring tets) need not descend even for
  /// large damping: on the vertebrae the clamped steps stalled at μ ≈ 1e20 or ran to the
  /// iteration limit. false (the default): clamp and search, as the paper.
  bool hold_clamped_tets = false;
  double damping_start = 1.0;
  double damping_growth = 10.0;
  /// Equilibrium solves (line search, initial fit).
  EquilibriumOptions equilibrium{};
  WoodburySolverOptions woodbury{};
  /// Empty when valid; otherwise one line naming the field, its value and the constraint.
  std::optional<std::string> validate() const;
};

/// One row of the report: one Gauss–Newton iteration (or the initial fit).
struct GaussNewtonIteration {
  RegistrationStage stage = RegistrationStage::kAttachments;
  int iteration = 0;                ///< within the stage, from 1
  double objective = 0.0;           ///< Φ after the iteration
  double objective_before = 0.0;    ///< Φ at its start (same constraints)
  double predicted_decrease = 0.0;  ///< the Gauss–Newton model's decrease for the full step
  double step = 0.0;                ///< η taken (0: rejected)
  /// Misfit of the stage's markers after the iteration (landmarks or ICP markers; attachments in
  /// the attachment stage), metres.
  double marker_error_mean = 0.0;
  double marker_error_max = 0.0;
  int equilibrium_solves = 0;
  int clamped_tets = 0;           ///< tets whose Fp eigenvalues were clamped
  bool projected_search = false;  ///< the projected-path search ran (projected_search_fallback)
  /// μ of the step taken (GaussNewtonOptions::damped_step_trials); 0: the plain Gauss–Newton step.
  double damping = 0.0;
  double jacobian_seconds = 0.0;  ///< tangent factorisation + Z
  double woodbury_seconds = 0.0;  ///< H solve
  double line_search_seconds = 0.0;
  double seconds = 0.0;  ///< whole iteration
};

enum class GaussNewtonTermination {
  kMaxIterations,      ///< the last stage hit its iteration limit
  kMarkerTolerance,    ///< every ICP marker within max_marker_error
  kSmallStep,          ///< η below min_step
  kSmallDecrease,      ///< relative decrease below tolerance
  kLineSearchFailed,   ///< no η in (0, max_step] decreased Φ
  kEquilibriumFailed,  ///< the equilibrium at the start could not be solved
  kLinearSolveFailed,  ///< tangent stiffness not positive definite, or Woodbury failed
  kInvalidInput,       ///< options, sizes, constraints (see message)
};
const char* to_string(GaussNewtonTermination termination);

struct GaussNewtonSummary {
  GaussNewtonTermination termination = GaussNewtonTermination::kInvalidInput;
  std::string message;  ///< why, for kInvalidInput and the failures
  std::vector<GaussNewtonIteration> iterations;
  double initial_objective = 0.0;  ///< Φ of the final stage's constraints at the template
  double final_objective = 0.0;
  double marker_error_mean = 0.0;  ///< final stage's markers at the end, metres
  double marker_error_max = 0.0;
  int equilibrium_solves = 0;
  double seconds = 0.0;
  bool usable() const {
    return termination != GaussNewtonTermination::kInvalidInput &&
           termination != GaussNewtonTermination::kEquilibriumFailed;
  }
  std::string brief_report() const;
  std::string full_report() const;
};

/// The inputs of a registration, in the tet mesh's frame (embedded material points).
struct RegistrationConstraints {
  /// Springs of f_net (kind kAttachment; weight = spring stiffness, N/m).
  std::vector<PointConstraint> attachments;
  /// Landmarks with correspondence (kind kLandmark; weight multiplies α).
  std::vector<PointConstraint> landmarks;
  /// ICP markers: world points to be met by the closest surface point (weight 1 each).
  std::vector<Eigen::Vector3d> icp_markers;
};

struct RegistrationResult {
  Eigen::VectorXd s;  ///< 6m plastic state
  Eigen::VectorXd x;  ///< 3n equilibrium positions
  GaussNewtonSummary summary;
};

/// Called after each iteration (and after the initial fit) for progress output.
using GaussNewtonProgress = std::function<void(const GaussNewtonIteration&)>;

/// Everything a registration needs to continue exactly where it stopped. After the initial fit
/// the loop carries no state but (s, x) and its position in the stages: every equilibrium is
/// warm-started from x, ICP closest points and a free object's rigid frame are found at x, and
/// the solvers' factorisations are rebuilt per iteration. So a run resumed from a checkpoint
/// does the same arithmetic as one that never stopped (tools/register writes one to
/// OUTDIR/checkpoint.sinew after every iteration; `sinew-register --resume`).
struct GaussNewtonCheckpoint {
  bool free_object = false;  ///< written by register_free (true) or register_attached (false)
  /// Where to continue: the stage and its iteration (from 1) to run next; std::nullopt when
  /// every stage is done (only the summary is left to compute).
  std::optional<RegistrationStage> next_stage;
  int next_iteration = 1;
  /// The last finished stage's termination: the run's when next_stage is empty.
  GaussNewtonTermination termination = GaussNewtonTermination::kMaxIterations;
  Eigen::VectorXd s;                             ///< 6m plastic state
  Eigen::VectorXd x;                             ///< 3n equilibrium positions
  std::vector<GaussNewtonIteration> iterations;  ///< so far, the initial fit's included
  double initial_objective = 0.0;                ///< GaussNewtonSummary::initial_objective
  int equilibrium_solves = 0;                    ///< so far
  double seconds = 0.0;                          ///< registration time so far
};

/// Called after the initial fit and after each Gauss–Newton iteration (once its stage's
/// termination tests have run) with the state to resume from; for writing checkpoints.
using GaussNewtonCheckpointCallback = std::function<void(const GaussNewtonCheckpoint&)>;

/// Runs the staged registration from the template (s = identity, x = rest positions).
/// closest_point is needed when there are ICP markers (nullptr otherwise). With resume (a
/// checkpoint of a run with the same energy, constraints and options), the first equilibrium, the
/// initial fit and the finished iterations are skipped and the run continues from resume's (s,
/// x); the result equals the uninterrupted run's. A checkpoint that does not fit (sizes, mode,
/// stage) gives kInvalidInput.
RegistrationResult register_attached(const PlasticElasticEnergy& energy,
                                     const RegistrationConstraints& constraints,
                                     ClosestSurfacePoint* closest_point,
                                     const GaussNewtonOptions& options = {},
                                     const GaussNewtonProgress& progress = {},
                                     const GaussNewtonCheckpointCallback& checkpoint = {},
                                     const GaussNewtonCheckpoint* resume = nullptr);

/// Un-attached ("free-flying") objects, §3.6: no attachments, only landmarks and/or ICP markers
/// (at least 3). The template is first aligned rigidly (landmark correspondences, else centroids
/// and ICP); the equilibrium of each plastic state is found with six pinned dofs and moved to the
/// rigid frame (R, t) of eqs. 19–20 over the stage's marker points; the Jacobian uses the
/// Singular Lemma (ii) and the rigid correction that keeps eqs. 19–20 (free_constraint_jacobian);
/// and after every accepted step (R, t) is re-fitted to the markers in closed form (Kabsch, with
/// closest points re-found for ICP markers) — the block-coordinate descent of §3.6. Stages
/// landmarks → ICP markers. Options as for register_attached (beta unused).
/// The run works with the scan's points moved rigidly onto the template (the landmarks' fit, else
/// the centroids) and rounded to 2⁻²⁶ of the template's diagonal, so that the scan in another
/// pose gives the same result, moved (result.x is in the scan's frame).
/// checkpoint and resume as for register_attached (a free object's checkpoint x is in that
/// template-side frame).
RegistrationResult register_free(const PlasticElasticEnergy& energy,
                                 const RegistrationConstraints& constraints,
                                 ClosestSurfacePoint* closest_point,
                                 const GaussNewtonOptions& options = {},
                                 const GaussNewtonProgress& progress = {},
                                 const GaussNewtonCheckpointCallback& checkpoint = {},
                                 const GaussNewtonCheckpoint* resume = nullptr);

/// The rows of the Gauss–Newton system for objective terms at (s, x): Z = −[√c_k A_k]·K⁻¹·∂f/∂s
/// (eq. 12; r x 6m, r = 3·terms.size()), returned TRANSPOSED as Zt (6m x r, the layout the
/// Woodbury solver and the products with it want), and the residual r = [√c_k (A_k x + b_k)] (r),
/// with
/// K = ∂f_net/∂x = ∂²E/∂x² + the springs' Hessian factorised into tangent (its symbolic analysis
/// is reused while the pattern does not change). energy must use the exact stiffness (no
/// projection) and full storage. std::nullopt with why set when K is not positive definite.
/// storage, when given, is memory for Zᵀ (e.g. WoodburySolver::release_constraint_rows()), used
/// when its size matches (its values are overwritten) and left alone otherwise.
struct ConstraintJacobian {
  Eigen::MatrixXd Zt;  ///< Zᵀ, 6m x r
  Eigen::VectorXd residual;
};
std::optional<ConstraintJacobian> constraint_jacobian(
    PlasticElasticEnergy& energy, const PointConstraints& springs, const PointConstraints& terms,
    const Eigen::Ref<const Eigen::VectorXd>& s, const Eigen::Ref<const Eigen::VectorXd>& x,
    SparseCholesky& tangent, std::string* why = nullptr, Eigen::MatrixXd* storage = nullptr);

/// constraint_jacobian for a free object at a static equilibrium x satisfying eqs. 19–20 for
/// frame: K (exact, full storage, singular along the rigid motions) is factorised with six pinned
/// dofs in tangent, and Z = −C·P·K⁺·∂f/∂s with K⁺ the Singular Lemma (ii) solve and P = I −
/// Ψ(GΨ)⁻¹G the rigid correction that keeps the stabilisation constraints (G their Jacobian).
std::optional<ConstraintJacobian> free_constraint_jacobian(
    PlasticElasticEnergy& energy, const PointConstraints& terms,
    const RigidStabilisation& stabilisation, const RigidFrame& frame,
    const Eigen::Ref<const Eigen::VectorXd>& s, const Eigen::Ref<const Eigen::VectorXd>& x,
    RigidNullspaceSolver& tangent, std::string* why = nullptr, Eigen::MatrixXd* storage = nullptr);

}  // namespace sinew::offline
