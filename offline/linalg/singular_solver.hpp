#pragma once
/// Singular Lemma (ii) of seed 003 (§3.5) for the tangent stiffness K of a free object at a static
/// equilibrium: K is symmetric positive semi-definite with the six rigid motions as its nullspace
/// (the Nullspace Lemma, §3.6), and for b in the range of K the system K y = b has exactly one
/// solution orthogonal to the nullspace, the y of eq. 15.
///
/// Eq. 15's bordered matrix is indefinite, which rules out a Cholesky factorisation. The same y is
/// found with one: K with six pinned dofs (offline/rigid/rigid_motion.hpp, rigid_pin_dofs) is
/// positive definite; its solution solves K y = b in every row (b ∈ R(K), and pinning only picks
/// one member of the family y + Σ μ_i ψ_i), and the orthogonal projection onto N(K)^⊥ then gives
/// eq. 15's y. tests/offline/test_singular_solver.cpp checks this against a dense solve of eq. 15
/// and the pseudo-inverse.
///
/// Right-hand sides are first projected onto R(K) = N(K)^⊥ (b − ΨΨᵀb): the Gauss–Newton right-hand
/// sides are in the range by construction (§3.6), up to the equilibrium's residual.

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <array>
#include <optional>

#include "offline/linalg/sparse_cholesky.hpp"

namespace sinew::offline {

class RigidNullspaceSolver {
 public:
  explicit RigidNullspaceSolver(const SparseCholeskyOptions& options = {});

  /// Factorises K (3n x 3n, upper triangle read) whose nullspace is spanned by the rigid motions
  /// at positions x (3n). The symbolic analysis is kept while K's pattern does not change.
  /// kInvalidInput when the sizes differ or x is (nearly) collinear; kNotPositiveDefinite when
  /// the pinned K is not positive definite (x is not a stable equilibrium).
  SparseCholeskyStatus factorise(const Eigen::SparseMatrix<double>& K,
                                 const Eigen::Ref<const Eigen::VectorXd>& x);

  /// Solves K Y = proj_R(B) for all columns of B (3n x k) with Y ⟂ N(K). solution is resized.
  SparseCholeskyStatus solve(const Eigen::Ref<const Eigen::MatrixXd>& rhs,
                             Eigen::MatrixXd& solution);

  /// Orthonormal basis of N(K) (3n x 6) at the x of the last factorise().
  const Eigen::Matrix<double, Eigen::Dynamic, 6>& nullspace() const { return nullspace_; }
  /// The six pinned dofs of the last factorise().
  const std::array<Eigen::Index, 6>& pins() const { return pins_; }

 private:
  SparseCholesky cholesky_;
  Eigen::SparseMatrix<double> pinned_;
  Eigen::Matrix<double, Eigen::Dynamic, 6> nullspace_;
  std::array<Eigen::Index, 6> pins_{};
};

}  // namespace sinew::offline
