#pragma once
/// The one vectorisation convention of Sinew: vec(A) of a 3x3 matrix is COLUMN-MAJOR,
///   vec(A) = [A00, A10, A20, A01, A11, A21, A02, A12, A22],   vec(A)[i + 3j] = A(i, j),
/// which is exactly Eigen's storage order, so vec/unvec are plain maps. Every 9-vector and 9x9
/// matrix in common/ (dF/dx, P, ∂P/∂F, dR/dF, dS/dF, d²R/dF²) uses it. Note that the slides of
/// seed 002 stack F row by row; our dF/dx is their B with rows permuted accordingly.
///
/// A 9x9 "derivative" D of a matrix-valued function G(F) has D(a, b) = ∂ vec(G)_a / ∂ vec(F)_b,
/// i.e. column b is vec(∂G/∂F_b) (seed 003, §3.7 writes ∂R/∂F_i for this column).

#include <Eigen/Core>

namespace sinew::common {

using Vector9d = Eigen::Matrix<double, 9, 1>;
using Matrix9d = Eigen::Matrix<double, 9, 9>;

/// Position of A(row, col) in vec(A).
constexpr int vec_index(int row, int col) {
  return row + 3 * col;
}

/// Column-major vec of a 3x3 matrix (9).
inline Vector9d vec(const Eigen::Matrix3d& A) {
  return Eigen::Map<const Vector9d>(A.data());
}

/// Inverse of vec: the 3x3 matrix whose column-major vec is v.
inline Eigen::Matrix3d unvec(const Vector9d& v) {
  return Eigen::Map<const Eigen::Matrix3d>(v.data());
}

}  // namespace sinew::common
