#pragma once
/// The stabilised static equilibrium of a free object, seed 003 §3.6 eqs. 18–20, as one
/// constrained problem in Ipopt (the paper used Knitro):
///   min_x E(Fp(s), x)   s.t.   g_c(x) = 0 (eq. 19, centroid),   g_r(x) = 0 (eq. 20, rotation),
/// with the exact gradient, the constraint Jacobian and the Hessian of the Lagrangian
/// K + Σ λ_i ∇²g_i, whose rotation part uses the second derivatives of the polar decomposition
/// (offline/rigid/rigid_stabilisation.hpp, common/geometry/polar_decomposition.hpp). E is invariant
/// under rigid motions, so at the solution f_e = 0 and the multipliers vanish.
///
/// The registration itself takes the cheaper, equivalent route (EquilibriumSolver's pinned Newton
/// and RigidStabilisation::move_to, which satisfies eqs. 19–20 in closed form); this solver is the
/// paper's formulation, kept for cross-checks and for Ipopt's derivative checker (tests/offline/
/// test_free_equilibrium.cpp). The Hessian couples every pair of the marker points' tet vertices
/// (a dense block), so it suits meshes with up to a few hundred marker tets.
/// Ipopt's headers stay in free_equilibrium.cpp.

#include <Eigen/Core>
#include <optional>
#include <string>

#include "offline/equilibrium/equilibrium.hpp"
#include "offline/plastic/plastic_elastic_energy.hpp"
#include "offline/rigid/rigid_stabilisation.hpp"

namespace sinew::offline {

struct FreeEquilibriumOptions {
  int max_iterations = 200;  ///< Ipopt's max_iter, ≥ 0
  /// Converged when ‖f_e‖∞ ≤ force_tolerance·μh² (as EquilibriumOptions) and the constraints
  /// hold to constraint_tolerance (metres for eq. 19, radians for eq. 20); in (0, 1).
  double force_tolerance = 1e-8;
  double constraint_tolerance = 1e-10;
  int print_level = 0;  ///< Ipopt's print_level, [0, 12]
  /// Ipopt's derivative checker at the start x (tests only).
  IpoptDerivativeTest derivative_test = IpoptDerivativeTest::kNone;
  double derivative_test_tolerance = 1e-4;
  double derivative_test_perturbation = 1e-8;
};

struct FreeEquilibriumSummary {
  EquilibriumStatus status = EquilibriumStatus::kInvalidInput;
  int iterations = 0;
  std::optional<int> ipopt_return_code;
  std::optional<int> derivative_test_errors;  ///< when the checker ran
  double residual_norm = 0.0;                 ///< ‖f_e‖∞ at the returned x, newtons
  double force_scale = 0.0;                   ///< μh², newtons
  double constraint_violation = 0.0;          ///< ‖[g_c; g_r]‖∞ at the returned x
  double seconds = 0.0;
  bool converged() const { return status == EquilibriumStatus::kConverged; }
};

/// Solves eqs. 18–20 for the plastic state s (6m) from x (3n, in/out: the last Ipopt iterate when
/// it is finite). kInvalidInput for wrong sizes or a stabilisation of another mesh.
FreeEquilibriumSummary solve_free_equilibrium(const PlasticElasticEnergy& energy,
                                              const RigidStabilisation& stabilisation,
                                              const RigidFrame& frame,
                                              const Eigen::Ref<const Eigen::VectorXd>& s,
                                              Eigen::Ref<Eigen::VectorXd> x,
                                              const FreeEquilibriumOptions& options = {});

}  // namespace sinew::offline
