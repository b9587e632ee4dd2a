#pragma once
/// Symmetric block-tridiagonal matrices with 3x3 blocks, and their block LDLᵀ factorisation.
///
/// A beam's tangent stiffness couples only neighbouring nodes, so K_T (and K_T + ∇FᵀW∇F when every
/// image observation depends on one element's two nodes) is block-tridiagonal. Factorising it costs
/// O(n) instead of O(n³) for a dense solve. Storage is sized once by resize(); assembly, factor()
/// and solve() never allocate, which is what the real-time tracker (rt/) needs per frame.

#include <Eigen/Core>
#include <vector>

namespace sinew::common {

class BlockTridiagonal {
 public:
  BlockTridiagonal() = default;
  explicit BlockTridiagonal(int num_blocks) { resize(num_blocks); }

  /// Allocates storage for num_blocks x num_blocks blocks (3·num_blocks unknowns).
  void resize(int num_blocks);
  int num_blocks() const { return static_cast<int>(diagonal_.size()); }
  int size() const { return 3 * num_blocks(); }

  void set_zero();
  /// Diagonal block (i, i).
  Eigen::Matrix3d& diagonal(int i) { return diagonal_[i]; }
  const Eigen::Matrix3d& diagonal(int i) const { return diagonal_[i]; }
  /// Sub-diagonal block (i + 1, i); block (i, i + 1) is its transpose.
  Eigen::Matrix3d& lower(int i) { return lower_[i]; }
  const Eigen::Matrix3d& lower(int i) const { return lower_[i]; }

  /// Adds a 6x6 symmetric element matrix coupling blocks i and i + 1.
  void add_element(int i, const Eigen::Matrix<double, 6, 6>& Ke);
  /// The same, given only the blocks the matrix stores: Ke's first three columns (blocks (i, i)
  /// over (i + 1, i)) and its block (i + 1, i + 1). For assemblies that accumulate just these (the
  /// tracker's image term, per element and frame).
  template <typename Derived>
  void add_element_lower(int i, const Eigen::Matrix<double, 6, 3>& left_columns,
                         const Eigen::MatrixBase<Derived>& bottom_right) {
    diagonal_[i] += left_columns.topRows<3>();
    lower_[i] += left_columns.bottomRows<3>();
    diagonal_[i + 1] += bottom_right;
  }

  /// Replaces the rows and columns of the dofs with fixed[dof] != 0 by those of the identity, so a
  /// solve returns 0 there when the right-hand side is 0 there. fixed.size() == size().
  void apply_fixed_dofs(const std::vector<unsigned char>& fixed);

  /// y = A x (x, y of length size(); no allocation).
  void multiply(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::VectorXd> y) const;

  /// Dense copy, for tests and small reference solves.
  Eigen::MatrixXd to_dense() const;

 private:
  std::vector<Eigen::Matrix3d> diagonal_;
  std::vector<Eigen::Matrix3d> lower_;
};

/// Block LDLᵀ factorisation without pivoting: A = L·D·Lᵀ with unit block-lower-bidiagonal L and
/// block-diagonal D (Schur complements S_i). Works for symmetric positive-definite and for the
/// indefinite-but-nonsingular tangents met during Newton iterations; reports failure when a pivot
/// block is (numerically) singular, e.g. a free beam with no fixed dof.
class BlockTridiagonalLdlt {
 public:
  BlockTridiagonalLdlt() = default;
  explicit BlockTridiagonalLdlt(int num_blocks) { resize(num_blocks); }
  void resize(int num_blocks);

  /// Factorises A. Returns false if a pivot block's reciprocal condition estimate falls below
  /// pivot_tolerance (relative to the largest diagonal block norm) or is not finite.
  bool factor(const BlockTridiagonal& A, double pivot_tolerance = 1e-13);
  /// Solves A x = b in place (b holds x on return). Requires a successful factor().
  void solve_in_place(Eigen::Ref<Eigen::VectorXd> b) const;
  /// Solves A X = B for every column of B at once, in place: one pass over the blocks for all
  /// columns, whose independent arithmetic overlaps (a load fit's Jacobian columns and Newton
  /// step; no allocation).
  void solve_columns_in_place(Eigen::Ref<Eigen::MatrixXd> B) const;
  /// Number of negative eigenvalues of A (Sylvester's law of inertia on the pivot blocks).
  int negative_eigenvalue_count() const;

 private:
  std::vector<Eigen::Matrix3d> pivot_inverse_;  // S_i⁻¹
  std::vector<Eigen::Matrix3d> pivot_;          // S_i
  std::vector<Eigen::Matrix3d> multiplier_;     // L_i = A(i, i-1) S_{i-1}⁻¹, index i ≥ 1
};

}  // namespace sinew::common
