#pragma once
/// The plastic model of seed 003 (§3.2, eq. 2): a symmetric plastic deformation gradient Fp per
/// tet, parameterised by s ∈ R⁶, and everything the optimiser needs from it: Fp⁻¹, det Fp and their
/// first and second derivatives with respect to s, plus the eigenvalue clamp of §3.4.
///
/// Conventions
///  - s ↦ Fp exactly as eq. 2 (no √2, no identity offset; the paper's s1..s6 are s[0]..s[5] here):
///        Fp = [ s0 s1 s2 ;
///               s1 s3 s4 ;
///               s2 s4 s5 ],   so Fp = I is s = (1, 0, 0, 1, 0, 1) (identity_plastic_strain()).
///    The off-diagonal entries s1, s2, s4 each control two entries of Fp (the √2 weights of the
///    plastic-strain Laplacian account for that, see offline/plastic/plastic_strain_laplacian.hpp).
///  - vec(Fp) = Y s with the constant 9x6 matrix Y of appendix B (plastic_strain_basis()), vec the
///    column-major vec of common/geometry/matrix_vec.hpp: vec(A)[i + 3j] = A(i, j).
///  - A first derivative D of a matrix-valued G(s) is 9x6 with column k = vec(∂G/∂s_k).
///  - A second derivative is six 9x6 matrices, one per differentiation variable s_l:
///        d2[l].col(k) = vec(∂²G/∂s_k∂s_l),   i.e. d2[l] = ∂D/∂s_l,
///    symmetric in (k, l): d2[l].col(k) == d2[k].col(l) (the layout of d2RdF2 in
///    common/geometry/polar_decomposition.hpp).
///  - Global plastic state of m tets: s ∈ R⁶ᵐ, tet-major, tet t owns s[6t .. 6t+5]. (Appendix A
///    writes the same vector component-major, [s1 … s6] with s_i ∈ Rᵐ; that is a permutation.)

#include <Eigen/Core>
#include <array>
#include <optional>
#include <string>

#include "common/geometry/matrix_vec.hpp"

namespace sinew::offline {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Matrix9x6d = Eigen::Matrix<double, 9, 6>;

/// Number of plastic-strain parameters per tet.
inline constexpr int kPlasticStrainSize = 6;

/// Entries (row, col) of Fp that component k of s sets (row ≤ col); diagonal components set one.
struct PlasticStrainComponent {
  int row;
  int col;
};
inline constexpr std::array<PlasticStrainComponent, 6> kPlasticStrainComponents = {
    {{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}}};

/// True for the off-diagonal components 1, 2, 4 (the paper's s2, s3, s5).
constexpr bool is_off_diagonal_component(int k) {
  return k == 1 || k == 2 || k == 4;
}

/// Y (9x6, appendix B): vec(Fp) = Y s; column k is vec(∂Fp/∂s_k), with ones at the entries of
/// component k (two ones for off-diagonal components).
const Matrix9x6d& plastic_strain_basis();

/// s of the identity, (1, 0, 0, 1, 0, 1).
Vector6d identity_plastic_strain();

/// s of the scaled identity c·I.
Vector6d scaled_identity_plastic_strain(double c);

/// m copies of identity_plastic_strain(), tet-major (6m).
Eigen::VectorXd identity_plastic_strains(Eigen::Index num_tets);

/// Fp(s), eq. 2 (3x3 symmetric, dimensionless).
Eigen::Matrix3d plastic_strain_matrix(const Vector6d& s);

/// The s whose Fp is the symmetric part (A + Aᵀ)/2 of A; exact inverse of plastic_strain_matrix on
/// symmetric matrices.
Vector6d plastic_strain_vector(const Eigen::Matrix3d& A);

enum class PlasticStrainStatus {
  kPositiveDefinite,     ///< Fp symmetric positive definite: every field valid, det Fp > 0
  kNotPositiveDefinite,  ///< Fp invertible but with a negative eigenvalue: fields valid, but the
                         ///< plastic volume det Fp·V₀ may be ≤ 0; clamp before using physically
  kSingular,   ///< |det Fp| ≤ 1e-12·‖Fp‖³_F: Fp, det and its derivatives valid, Fp⁻¹
               ///< and its derivatives are not (filled with NaN)
  kNonFinite,  ///< s has NaN or infinite entries; nothing is valid
};

const char* to_string(PlasticStrainStatus status);

/// True when Fp⁻¹ (and its derivatives) exist: kPositiveDefinite or kNotPositiveDefinite.
constexpr bool is_invertible(PlasticStrainStatus status) {
  return status == PlasticStrainStatus::kPositiveDefinite ||
         status == PlasticStrainStatus::kNotPositiveDefinite;
}

enum class PlasticDerivativeOrder {
  kValue,   ///< Fp, Fp⁻¹, det Fp only
  kFirst,   ///< also the first derivatives
  kSecond,  ///< also the second derivatives
};

/// Fp(s), Fp⁻¹, det Fp and their derivatives with respect to s (layouts in the header comment).
/// Fields above the requested order are left zero.
struct PlasticStrainDerivatives {
  PlasticStrainStatus status = PlasticStrainStatus::kNonFinite;
  Eigen::Matrix3d Fp = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d Fp_inv = Eigen::Matrix3d::Zero();
  double det = 0.0;  ///< det Fp; the plastic rest volume is det·V₀ (eq. 1)

  Vector6d ddet_ds = Vector6d::Zero();  ///< ∂ det Fp / ∂s = Yᵀ vec(cof Fp) (6)
  Matrix6d d2det_ds2 = Matrix6d::Zero();  ///< ∂² det Fp / ∂s² = Yᵀ (∂²J/∂F²) Y (6x6, symmetric)
  /// 9x6, column k = vec(∂Fp⁻¹/∂s_k) = vec(−Fp⁻¹ E_k Fp⁻¹), E_k = ∂Fp/∂s_k.
  Matrix9x6d dFp_inv_ds = Matrix9x6d::Zero();
  /// d2Fp_inv_ds2[l].col(k) = vec(∂²Fp⁻¹/∂s_k∂s_l) = vec(Fp⁻¹E_kFp⁻¹E_lFp⁻¹ + Fp⁻¹E_lFp⁻¹E_kFp⁻¹).
  std::array<Matrix9x6d, 6> d2Fp_inv_ds2 = zero_second_derivatives();

  bool invertible() const { return is_invertible(status); }

  static std::array<Matrix9x6d, 6> zero_second_derivatives() {
    std::array<Matrix9x6d, 6> a;
    for (Matrix9x6d& m : a) m.setZero();
    return a;
  }
};

/// Evaluates Fp(s) and its inverse and determinant, with derivatives up to order. det and its
/// derivatives are polynomial in s (cofactor formulas) and valid whenever s is finite; Fp⁻¹ and its
/// derivatives only when the status is invertible. No allocation, never throws.
PlasticStrainDerivatives plastic_strain_derivatives(
    const Vector6d& s, PlasticDerivativeOrder order = PlasticDerivativeOrder::kFirst);

/// Default lower bound on the eigenvalues of Fp (seed 003, §3.4: "we use 0.01").
inline constexpr double kDefaultEigenvalueFloor = 0.01;

enum class EigenvalueClampStatus {
  kUnchanged,     ///< every eigenvalue was ≥ floor; s is returned bit for bit
  kClamped,       ///< at least one eigenvalue was raised to the floor
  kNonFinite,     ///< s had NaN or infinite entries; s is returned unchanged
  kInvalidFloor,  ///< floor was not finite and > 0; s is returned unchanged
  kInvalidSize,   ///< (whole state only) s.size() is not a multiple of 6; nothing is changed
};

const char* to_string(EigenvalueClampStatus status);

struct EigenvalueClamp {
  EigenvalueClampStatus status = EigenvalueClampStatus::kInvalidFloor;
  Vector6d s = Vector6d::Zero();  ///< the clamped plastic strain
  int clamped_eigenvalues = 0;    ///< how many eigenvalues were raised, 0..3
  /// Smallest eigenvalue of Fp before clamping (valid unless kNonFinite / kInvalidFloor).
  double min_eigenvalue = 0.0;
};

/// Keeps Fp symmetric positive definite (seed 003, §3.4): eigen-decomposes Fp = Q Λ Qᵀ and raises
/// every eigenvalue below floor to floor. The paper clamps the negative eigenvalues to 0.01;
/// raising everything below the floor also catches eigenvalues in [0, floor), which would keep Fp
/// (nearly) singular. Fixed-size eigen-solver, no allocation.
EigenvalueClamp clamp_plastic_strain_eigenvalues(const Vector6d& s,
                                                 double floor = kDefaultEigenvalueFloor);

/// Summary of clamping a whole plastic state.
struct PlasticStateClamp {
  EigenvalueClampStatus status = EigenvalueClampStatus::kInvalidFloor;  ///< worst over the tets
  Eigen::Index clamped_tets = 0;                                        ///< tets whose Fp changed
  /// First tet with non-finite entries, when status is kNonFinite.
  std::optional<Eigen::Index> non_finite_tet;
  double min_eigenvalue = 0.0;  ///< smallest eigenvalue over all tets before clamping
};

/// clamp_plastic_strain_eigenvalues on every tet of a global state s (6m, tet-major), in place.
/// Tets with non-finite entries are left as they are (and reported). No allocation.
PlasticStateClamp clamp_plastic_state_eigenvalues(Eigen::Ref<Eigen::VectorXd> s,
                                                  double floor = kDefaultEigenvalueFloor);

}  // namespace sinew::offline
