#pragma once
/// The options of the staged Gauss–Newton registration (offline/registration/gauss_newton.hpp):
/// objective weights, stage lengths and stopping tests, the ICP stage's continuation, the line
/// search and the step's damping. Each field keeps its one-line reason; the measurements behind
/// the defaults are in docs/registration.md, "Gauss–Newton options".
#include <optional>
#include <string>
#include <vector>

#include "offline/equilibrium/equilibrium.hpp"
#include "offline/linalg/woodbury_solver.hpp"
#include "offline/plastic/plastic_strain.hpp"

namespace sinew::offline {

struct GaussNewtonOptions {
  /// Objective weight α of landmarks and ICP markers (eq. 3), per metre² of misfit, against the
  /// dimensionless smoothness ½‖L s‖²; > 0. The paper used 1e9; 1e7 meets the markers as
  /// closely on a normalised mesh and keeps the field smooth (docs/registration.md, "Options").
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
  /// Factors in (0, 1]; empty (the default): the paper's plain ICP stage.
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
  /// along the markers and take the landmarks with it; with them kept, the anatomical
  /// correspondence the user gave holds the surface in place and both sets are met.
  /// They follow the stage's weight ramp (icp_weight_ramp) like the markers. false (the
  /// default): the paper's ICP stage.
  bool icp_stage_landmarks = false;
  /// Run the landmark stage (§3.4) before the ICP stage. Only consulted when icp_stage_landmarks
  /// is on and there are ICP markers (the ICP stage then fits the landmarks itself): false skips
  /// it: between a few landmarks met alone the plastic field is whatever is smoothest for them,
  /// which can leave the ICP markers further off than the constant initial fit did.
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
  /// (step, rigid re-fit, fresh closest points) no longer lowers the objective; the in-iteration
  /// test sees only one iteration's frozen closest points, under which Φ always falls. ≥ 0; 0
  /// (the default): the in-iteration test alone.
  int icp_no_progress_iterations = 0;
  /// The full step η = 1 is accepted without a Brent search when Φ decreased by at least this
  /// fraction of the Gauss–Newton model's predicted decrease (and no Fp was clamped); in [0, 1],
  /// 0 always searches (the paper's plain Brent). A search costs ~7 more equilibrium solves.
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
  /// a floor that stage steps freely along it and undoes the constant initial fit. Not applied in
  /// the landmark and ICP stages, whose markers do see uniform strains (a floor there slows them).
  double attachment_stage_damping_floor = 0.1;
  /// Eigenvalue floor of Fp after each step (§3.4: 0.01); > 0.
  double eigenvalue_floor = kDefaultEigenvalueFloor;
  /// The line search runs along clamp(s + d) − s, the Gauss–Newton step d with the floor applied
  /// to its full step. When many tets hit the floor that path can climb at every η; then (no η
  /// decreased Φ and some tet was clamped) a second Brent search runs along the projected path
  /// s(η) = clamp(s + η·d), which follows d itself for small η. false: the first search only.
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
  /// shapes the undamped ICP steps push many tets below the Fp floor and the searches stall; L²
  /// damping keeps the step smooth where the markers do not see it. 0 (the default): the plain
  /// step and search.
  int damped_step_trials = 0;
  /// Start each line-search equilibrium at the linear prediction x + η·(∂x/∂s)Δs (one more
  /// back-substitution per direction) instead of at x; when that solve fails, it is retried from
  /// x. false (the default): from x, as the paper (real shapes' first ICP steps can fail from x).
  bool predictor_warm_start = false;
  /// When a step clamps tets at the eigenvalue floor, solve for the step again with those tets'
  /// plastic state held (six penalty rows each in Z, 1e3 times its largest row norm: an active
  /// set), and search along that step; not in the ICP stage's ramp and point-to-plane phase,
  /// where hundreds of tets clamp per step and the extra rows make the Woodbury solve slow. The
  /// clamped step of the coupled system (L² links neighbouring tets) need not descend even for
  /// large damping. false (the default): clamp and search, as the paper.
  bool hold_clamped_tets = false;
  /// Held tets' six penalty rows cost 2·8·6m bytes each (their columns of Zᵀ and L⁺Zᵀ, m tets)
  /// and grow the dense capacitance; when they would take more than this, the tets are held
  /// exactly by elimination instead (WoodburySolver::set_constraint_rows_transposed_holding:
  /// the unheld solve's memory whatever their number). The bunny bent 90° (15,983 tets) was
  /// killed at 22 GB holding hundreds of tets by rows (issue 51, docs/registration.md); ≥ 0.
  double held_penalty_max_bytes = 2e9;
  /// A trust region on the damped steps' constant-strain part (damped_step_trials): a step at
  /// damping μ whose mean over the tets (its part along the six constant strains Ψ, which L² does
  /// not damp) is longer than this fraction of the mean of s, divided by √(1 + μ), gets the
  /// Marquardt term νΨΨᵀ with the ν that makes it that long; ≥ 0. Without it the damped step
  /// tends, as μ grows, to the Gauss–Newton step along Ψ instead of to 0 (issue 51,
  /// docs/registration.md). Only at μ ≥ rescue_min_damping. 0 (the default): no limit.
  double constant_strain_step_limit = 0.0;
  /// With predictor_warm_start: when the predicted start's equilibrium inverts a tet and the solve
  /// from x fails, score the trial at that inverted equilibrium (the stable neo-Hookean energy is
  /// finite there) instead of as a failure, on a direction damped at μ ≥ rescue_min_damping;
  /// on a less damped one the best such equilibrium is only taken when the iteration would
  /// otherwise take no step. false (the default): a failure.
  bool inverted_equilibrium_fallback = false;
  /// constant_strain_step_limit and inverted_equilibrium_fallback act on directions damped at
  /// μ ≥ this, i.e. once the plain step and the first damped ones failed; ≥ 0. Every step the
  /// benchmark's converging rows take is damped at μ ≤ 1e2 (the limit there took the cactus
  /// bulged 2x from 0.113 to 0.163 mm, the scoring the bunny twisted 45° from 0.087 to 0.382 mm,
  /// at μ = 0); the bunny bulged 2x stalls at μ ≥ 1e3 (issue 51, docs/registration.md).
  double rescue_min_damping = 1e3;
  double damping_start = 1.0;
  double damping_growth = 10.0;
  /// Equilibrium solves (line search, initial fit).
  EquilibriumOptions equilibrium{};
  WoodburySolverOptions woodbury{};
  /// Empty when valid; otherwise one line naming the field, its value and the constraint.
  std::optional<std::string> validate() const;
};

}  // namespace sinew::offline
