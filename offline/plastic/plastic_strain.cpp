#include "offline/plastic/plastic_strain.hpp"

#include "common/geometry/determinant.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>

namespace sinew::offline {

namespace {

using common::unvec;
using common::vec;
using common::vec_index;

// Relative singularity threshold: |det Fp| ≤ kSingularTolerance·‖Fp‖³_F.
constexpr double kSingularTolerance = 1e-12;

Matrix9x6d make_basis() {
  Matrix9x6d Y = Matrix9x6d::Zero();
  for (int k = 0; k < kPlasticStrainSize; ++k) {
    const auto [row, col] = kPlasticStrainComponents[static_cast<std::size_t>(k)];
    Y(vec_index(row, col), k) = 1.0;
    Y(vec_index(col, row), k) = 1.0;
  }
  return Y;
}

// Sylvester's criterion for a symmetric matrix: all leading principal minors positive.
bool is_positive_definite(const Eigen::Matrix3d& Fp, double det) {
  return Fp(0, 0) > 0.0 && Fp(0, 0) * Fp(1, 1) - Fp(0, 1) * Fp(1, 0) > 0.0 && det > 0.0;
}

}  // namespace

const Matrix9x6d& plastic_strain_basis() {
  static const Matrix9x6d Y = make_basis();
  return Y;
}

Vector6d identity_plastic_strain() {
  return scaled_identity_plastic_strain(1.0);
}

Vector6d scaled_identity_plastic_strain(double c) {
  Vector6d s;
  s << c, 0.0, 0.0, c, 0.0, c;
  return s;
}

Eigen::VectorXd identity_plastic_strains(Eigen::Index num_tets) {
  return identity_plastic_strain().replicate(num_tets, 1);
}

Eigen::Matrix3d plastic_strain_matrix(const Vector6d& s) {
  Eigen::Matrix3d Fp;
  Fp << s[0], s[1], s[2],  //
      s[1], s[3], s[4],    //
      s[2], s[4], s[5];
  return Fp;
}

Vector6d plastic_strain_vector(const Eigen::Matrix3d& A) {
  Vector6d s;
  for (int k = 0; k < kPlasticStrainSize; ++k) {
    const auto [row, col] = kPlasticStrainComponents[static_cast<std::size_t>(k)];
    s[k] = 0.5 * (A(row, col) + A(col, row));
  }
  return s;
}

const char* to_string(PlasticStrainStatus status) {
  switch (status) {
    case PlasticStrainStatus::kPositiveDefinite:
      return "positive definite";
    case PlasticStrainStatus::kNotPositiveDefinite:
      return "not positive definite";
    case PlasticStrainStatus::kSingular:
      return "singular";
    case PlasticStrainStatus::kNonFinite:
      return "non-finite";
  }
  return "unknown";
}

PlasticStrainDerivatives plastic_strain_derivatives(const Vector6d& s,
                                                    PlasticDerivativeOrder order) {
  PlasticStrainDerivatives d;
  if (!s.allFinite()) {
    d.status = PlasticStrainStatus::kNonFinite;
    return d;
  }
  const Matrix9x6d& Y = plastic_strain_basis();
  d.Fp = plastic_strain_matrix(s);
  d.det = d.Fp.determinant();
  const double scale = d.Fp.norm();
  if (!(std::abs(d.det) > kSingularTolerance * scale * scale * scale)) {
    d.status = PlasticStrainStatus::kSingular;
  } else {
    d.status = is_positive_definite(d.Fp, d.det) ? PlasticStrainStatus::kPositiveDefinite
                                                 : PlasticStrainStatus::kNotPositiveDefinite;
  }
  const bool invertible = d.invertible();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  d.Fp_inv = invertible ? Eigen::Matrix3d(d.Fp.inverse()) : Eigen::Matrix3d::Constant(nan);
  if (order == PlasticDerivativeOrder::kValue) return d;

  // Determinant: polynomial in s, valid for any finite s (chain rule through vec(Fp) = Y s).
  d.ddet_ds.noalias() = Y.transpose() * vec(common::determinant_gradient(d.Fp));
  if (order == PlasticDerivativeOrder::kSecond) {
    const Matrix9x6d H_Y = common::determinant_hessian(d.Fp) * Y;
    d.d2det_ds2.noalias() = Y.transpose() * H_Y;
  }

  if (!invertible) {
    d.dFp_inv_ds.setConstant(nan);
    if (order == PlasticDerivativeOrder::kSecond) {
      for (Matrix9x6d& m : d.d2Fp_inv_ds2) m.setConstant(nan);
    }
    return d;
  }

  // N_k = Fp⁻¹ E_k; ∂Fp⁻¹/∂s_k = −N_k Fp⁻¹.
  std::array<Eigen::Matrix3d, 6> N;
  for (int k = 0; k < kPlasticStrainSize; ++k) {
    N[static_cast<std::size_t>(k)] = d.Fp_inv * unvec(Y.col(k));
    d.dFp_inv_ds.col(k) = vec(-N[static_cast<std::size_t>(k)] * d.Fp_inv);
  }
  if (order != PlasticDerivativeOrder::kSecond) return d;

  // ∂²Fp⁻¹/∂s_k∂s_l = (N_k N_l + N_l N_k) Fp⁻¹, symmetric in (k, l).
  for (std::size_t l = 0; l < 6; ++l) {
    for (std::size_t k = 0; k <= l; ++k) {
      const common::Vector9d column = vec((N[k] * N[l] + N[l] * N[k]) * d.Fp_inv);
      d.d2Fp_inv_ds2[l].col(static_cast<Eigen::Index>(k)) = column;
      d.d2Fp_inv_ds2[k].col(static_cast<Eigen::Index>(l)) = column;
    }
  }
  return d;
}

const char* to_string(EigenvalueClampStatus status) {
  switch (status) {
    case EigenvalueClampStatus::kUnchanged:
      return "unchanged";
    case EigenvalueClampStatus::kClamped:
      return "clamped";
    case EigenvalueClampStatus::kNonFinite:
      return "non-finite plastic strain";
    case EigenvalueClampStatus::kInvalidFloor:
      return "invalid eigenvalue floor";
    case EigenvalueClampStatus::kInvalidSize:
      return "plastic state size is not a multiple of 6";
  }
  return "unknown";
}

EigenvalueClamp clamp_plastic_strain_eigenvalues(const Vector6d& s, double floor) {
  EigenvalueClamp result;
  result.s = s;
  if (!std::isfinite(floor) || !(floor > 0.0)) {
    result.status = EigenvalueClampStatus::kInvalidFloor;
    return result;
  }
  if (!s.allFinite()) {
    result.status = EigenvalueClampStatus::kNonFinite;
    return result;
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(plastic_strain_matrix(s));
  const Eigen::Vector3d& lambda = eigen.eigenvalues();  // ascending
  result.min_eigenvalue = lambda[0];
  if (lambda[0] >= floor) {
    result.status = EigenvalueClampStatus::kUnchanged;
    return result;
  }
  result.clamped_eigenvalues = static_cast<int>((lambda.array() < floor).count());
  const Eigen::Vector3d clamped = lambda.cwiseMax(floor);
  const Eigen::Matrix3d& Q = eigen.eigenvectors();
  result.s = plastic_strain_vector(Q * clamped.asDiagonal() * Q.transpose());
  result.status = EigenvalueClampStatus::kClamped;
  return result;
}

PlasticStateClamp clamp_plastic_state_eigenvalues(Eigen::Ref<Eigen::VectorXd> s, double floor) {
  PlasticStateClamp summary;
  if (!std::isfinite(floor) || !(floor > 0.0)) {
    summary.status = EigenvalueClampStatus::kInvalidFloor;
    return summary;
  }
  if (s.size() % kPlasticStrainSize != 0) {
    summary.status = EigenvalueClampStatus::kInvalidSize;
    return summary;
  }
  summary.status = EigenvalueClampStatus::kUnchanged;
  summary.min_eigenvalue = std::numeric_limits<double>::infinity();
  const Eigen::Index m = s.size() / kPlasticStrainSize;
  for (Eigen::Index t = 0; t < m; ++t) {
    const EigenvalueClamp c = clamp_plastic_strain_eigenvalues(
        s.segment<kPlasticStrainSize>(kPlasticStrainSize * t), floor);
    if (c.status == EigenvalueClampStatus::kNonFinite) {
      if (!summary.non_finite_tet) summary.non_finite_tet = t;
      summary.status = EigenvalueClampStatus::kNonFinite;
      continue;
    }
    summary.min_eigenvalue = std::min(summary.min_eigenvalue, c.min_eigenvalue);
    if (c.status == EigenvalueClampStatus::kClamped) {
      s.segment<kPlasticStrainSize>(kPlasticStrainSize * t) = c.s;
      ++summary.clamped_tets;
      if (summary.status == EigenvalueClampStatus::kUnchanged) {
        summary.status = EigenvalueClampStatus::kClamped;
      }
    }
  }
  return summary;
}

}  // namespace sinew::offline
