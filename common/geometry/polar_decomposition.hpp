#pragma once
/// Polar decomposition F = R·S of a 3x3 matrix (R a rotation, det R = +1; S symmetric, positive
/// definite when det F > 0) and its first and second derivatives with respect to the entries of F,
/// by the Sylvester-equation recipe of seed 003 (§3.7, eqs. 21–24; appendix E, eqs. 47–52).
///
/// All 9-vectors and 9x9 matrices use the column-major vec of common/geometry/matrix_vec.hpp:
/// dRdF(a, b) = ∂vec(R)_a / ∂vec(F)_b, so column b is vec(∂R/∂F_b).

#include <Eigen/Core>
#include <array>

#include "common/geometry/matrix_vec.hpp"

namespace sinew::common {

enum class PolarStatus {
  kSuccess,                 ///< det F > 0: R, S and (if asked) the derivatives are valid
  kNonPositiveDeterminant,  ///< det F ≤ 0: R, S are valid (S indefinite), derivatives are not
  kSingularSylvester,  ///< S ⊕ S is (numerically) singular: F nearly singular, no derivatives
  kNonFinite,          ///< F has NaN or infinite entries; nothing is valid
};

const char* to_string(PolarStatus status);

/// F = R·S. When det F ≤ 0 the decomposition is still returned with det R = +1 and a symmetric
/// S = Rᵀ F that has a non-positive eigenvalue (the smallest singular value takes the sign of
/// det F); status then says kNonPositiveDeterminant.
struct PolarDecomposition {
  PolarStatus status = PolarStatus::kNonFinite;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();  ///< rotation, RᵀR = I, det R = +1
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();      ///< symmetric stretch
};

/// Polar decomposition by a fixed-size Jacobi SVD, F = U Σ Vᵀ, R = U Vᵀ, S = V Σ Vᵀ (with the last
/// column of U and the last singular value negated when det(U Vᵀ) < 0). Robust for any F,
/// including rotations by ~π and repeated or tiny singular values. No allocation.
PolarDecomposition polar_decomposition(const Eigen::Matrix3d& F);

enum class PolarDerivativeOrder {
  kFirst,   ///< dRdF and dSdF only
  kSecond,  ///< also d2RdF2 and d2SdF2
};

/// Nine zero 9x9 matrices (Eigen matrices are not zeroed by default construction).
inline std::array<Matrix9d, 9> zero_matrix9d_array() {
  std::array<Matrix9d, 9> a;
  for (Matrix9d& m : a) m.setZero();
  return a;
}

/// R, S and their derivatives with respect to the entries of F (column-major vec).
///
/// Second derivatives are stored as nine 9x9 matrices, one per differentiation variable F_j:
///   d2RdF2[j](a, i) = ∂² vec(R)_a / ∂F_i ∂F_j,
/// i.e. d2RdF2[j] = ∂ dRdF / ∂F_j, and column i of d2RdF2[j] is vec(∂²R/∂F_i∂F_j). The tensor is
/// symmetric in (i, j): d2RdF2[j].col(i) == d2RdF2[i].col(j). The same layout holds for d2SdF2.
struct PolarDerivatives {
  PolarStatus status = PolarStatus::kNonFinite;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
  Matrix9d dRdF = Matrix9d::Zero();  ///< 9x9, column b = vec(∂R/∂F_b)  (seed 003, eq. 21)
  Matrix9d dSdF = Matrix9d::Zero();  ///< 9x9, column b = vec(∂S/∂F_b)  (seed 003, eq. 24)
  /// Layout above; zero unless order == kSecond (seed 003, eq. 49).
  std::array<Matrix9d, 9> d2RdF2 = zero_matrix9d_array();
  /// Layout above; zero unless order == kSecond (seed 003, eqs. 50–52).
  std::array<Matrix9d, 9> d2SdF2 = zero_matrix9d_array();
};

/// The derivatives of the polar decomposition of F. Valid only when status == kSuccess, which
/// requires det F > 0 and 2·σ_min(F) > 1e-12·σ_max(F) (the smallest eigenvalue of S ⊕ S). Never
/// throws; on failure the derivative fields are left zero and R, S are as in polar_decomposition.
/// Cost: one 9x9 LU of S ⊕ S, solved for 9 (first order) plus 45 (second order) right-hand sides.
PolarDerivatives polar_decomposition_derivatives(
    const Eigen::Matrix3d& F, PolarDerivativeOrder order = PolarDerivativeOrder::kFirst);

/// The Kronecker sum S ⊕ S = S ⊗ I + I ⊗ S (9x9) that maps vec(X) to vec(S X + X S) for symmetric
/// S: seed 003, eq. 23 with A = B = S, read as (Bᵀ ⊕ A) vec(X) = vec(C) (the printed equation puts
/// the inverse on the wrong side).
Matrix9d kronecker_sum(const Eigen::Matrix3d& S);

}  // namespace sinew::common
