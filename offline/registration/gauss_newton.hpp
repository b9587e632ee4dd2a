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

#include "offline/plastic/plastic_elastic_energy.hpp"
#include "offline/registration/checkpoint.hpp"
#include "offline/registration/closest_point.hpp"
#include "offline/registration/constraint_jacobian.hpp"
#include "offline/registration/gauss_newton_options.hpp"
#include "offline/registration/gauss_newton_summary.hpp"
#include "offline/registration/line_search.hpp"
#include "offline/registration/stages.hpp"

namespace sinew::offline {

struct RegistrationResult {
  Eigen::VectorXd s;  ///< 6m plastic state
  Eigen::VectorXd x;  ///< 3n equilibrium positions
  GaussNewtonSummary summary;
};

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

}  // namespace sinew::offline
