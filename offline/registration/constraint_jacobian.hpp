#pragma once
/// The Gauss–Newton system's rows Z (seed 003 eq. 12): how the objective terms' residuals move
/// with the plastic state through the static equilibrium, for an attached object (tangent
/// stiffness solve) and a free one (Singular Lemma (ii) and the rigid correction of §3.6).
#include <Eigen/Core>
#include <optional>
#include <string>

#include "offline/constraints/constraints.hpp"
#include "offline/linalg/singular_solver.hpp"
#include "offline/linalg/sparse_cholesky.hpp"
#include "offline/plastic/plastic_elastic_energy.hpp"
#include "offline/rigid/rigid_stabilisation.hpp"

namespace sinew::offline {

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
