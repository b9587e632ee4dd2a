#include "common/geometry/polar_decomposition.hpp"

#include <Eigen/LU>
#include <Eigen/SVD>

namespace sinew::common {

namespace {

// Below this ratio σ_min/σ_max the Sylvester operator S ⊕ S (eigenvalues σ_a + σ_b) is treated as
// singular: derivatives would scale like 1/σ_min and carry no useful digits.
constexpr double kSingularRatio = 0.5e-12;

// ∂F/∂F_b: the unit matrix with a one at (row, col) of vec index b.
Eigen::Matrix3d unit_matrix(int b) {
  Eigen::Matrix3d E = Eigen::Matrix3d::Zero();
  E(b % 3, b / 3) = 1.0;
  return E;
}

struct Svd3 {
  Eigen::Matrix3d U;
  Eigen::Matrix3d V;
  Eigen::Vector3d sigma;  // signed: sigma(2) < 0 when det F < 0
};

Svd3 signed_svd(const Eigen::Matrix3d& F) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Svd3 out{svd.matrixU(), svd.matrixV(), svd.singularValues()};
  // Make U Vᵀ a proper rotation: move the reflection into the smallest singular value.
  if (out.U.determinant() * out.V.determinant() < 0.0) {
    out.U.col(2) *= -1.0;
    out.sigma(2) *= -1.0;
  }
  return out;
}

}  // namespace

const char* to_string(PolarStatus status) {
  switch (status) {
    case PolarStatus::kSuccess:
      return "success";
    case PolarStatus::kNonPositiveDeterminant:
      return "non-positive determinant (det F <= 0)";
    case PolarStatus::kSingularSylvester:
      return "singular Sylvester operator S (+) S (F nearly singular)";
    case PolarStatus::kNonFinite:
      return "non-finite input";
  }
  return "unknown";
}

Matrix9d kronecker_sum(const Eigen::Matrix3d& S) {
  // (S ⊗ I + I ⊗ S)(i + 3j, k + 3l) = S(j, l) δ_ik + δ_jl S(i, k), for column-major vec.
  Matrix9d K = Matrix9d::Zero();
  for (int j = 0; j < 3; ++j) {
    for (int l = 0; l < 3; ++l) {
      for (int i = 0; i < 3; ++i) {
        K(i + 3 * j, i + 3 * l) += S(j, l);
        if (j == l) {
          for (int k = 0; k < 3; ++k) K(i + 3 * j, k + 3 * l) += S(i, k);
        }
      }
    }
  }
  return K;
}

PolarDecomposition polar_decomposition(const Eigen::Matrix3d& F) {
  PolarDecomposition out;
  if (!F.allFinite()) return out;  // status kNonFinite
  const Svd3 svd = signed_svd(F);
  out.R = svd.U * svd.V.transpose();
  out.S = svd.V * svd.sigma.asDiagonal() * svd.V.transpose();
  out.S = 0.5 * (out.S + out.S.transpose()).eval();  // exactly symmetric
  out.status = svd.sigma(2) > 0.0 ? PolarStatus::kSuccess : PolarStatus::kNonPositiveDeterminant;
  return out;
}

PolarDerivatives polar_decomposition_derivatives(const Eigen::Matrix3d& F,
                                                 PolarDerivativeOrder order) {
  PolarDerivatives out;
  if (!F.allFinite()) return out;  // status kNonFinite
  const Svd3 svd = signed_svd(F);
  out.R = svd.U * svd.V.transpose();
  out.S = svd.V * svd.sigma.asDiagonal() * svd.V.transpose();
  out.S = 0.5 * (out.S + out.S.transpose()).eval();
  if (!(svd.sigma(2) > 0.0)) {
    out.status = PolarStatus::kNonPositiveDeterminant;
    return out;
  }
  if (svd.sigma(2) <= kSingularRatio * svd.sigma(0)) {
    out.status = PolarStatus::kSingularSylvester;
    return out;
  }
  out.status = PolarStatus::kSuccess;

  const Eigen::Matrix3d& R = out.R;
  const Eigen::Matrix3d S_inv = svd.V * svd.sigma.cwiseInverse().asDiagonal() * svd.V.transpose();
  // S ⊕ S is symmetric positive definite here (eigenvalues σ_a + σ_b > 0); factor it once.
  const Eigen::PartialPivLU<Matrix9d> sylvester(kronecker_sum(out.S));

  // First order. Seed 003, eq. 22: ∂(FᵀF)/∂F_b = E_bᵀF + FᵀE_b = ∂S/∂F_b S + S ∂S/∂F_b, solved by
  // eq. 24; then eq. 21: ∂R/∂F_b = (E_b − R ∂S/∂F_b) S⁻¹.
  Matrix9d rhs;
  for (int b = 0; b < 9; ++b) {
    const int row = b % 3;
    const int col = b / 3;
    Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
    C.row(col) += F.row(row);              // E_bᵀ F
    C.col(col) += F.row(row).transpose();  // Fᵀ E_b
    rhs.col(b) = vec(C);
  }
  out.dSdF = sylvester.solve(rhs);
  std::array<Eigen::Matrix3d, 9> dS;
  std::array<Eigen::Matrix3d, 9> dR;
  for (int b = 0; b < 9; ++b) {
    dS[b] = unvec(out.dSdF.col(b));
    dR[b] = (unit_matrix(b) - R * dS[b]) * S_inv;
    out.dRdF.col(b) = vec(dR[b]);
  }
  if (order == PolarDerivativeOrder::kFirst) return out;

  // Second order, symmetric in (i, j): 45 distinct pairs. Seed 003, eqs. 50–52:
  //   (S ⊕ S) vec(∂²S/∂F_i∂F_j) = vec(E_iᵀE_j + E_jᵀE_i − ∂S_i ∂S_j − ∂S_j ∂S_i),
  // then eq. 49 (∂²F/∂F_i∂F_j = 0):
  //   ∂²R/∂F_i∂F_j = (−R ∂²S/∂F_i∂F_j − ∂R_j ∂S_i − ∂R_i ∂S_j) S⁻¹.
  Eigen::Matrix<double, 9, 45> rhs2;
  int pair = 0;
  for (int j = 0; j < 9; ++j) {
    for (int i = 0; i <= j; ++i, ++pair) {
      Eigen::Matrix3d C = -(dS[i] * dS[j] + dS[j] * dS[i]);
      // E_iᵀ E_j = δ(row_i, row_j) e_{col_i} e_{col_j}ᵀ
      if (i % 3 == j % 3) {
        C(i / 3, j / 3) += 1.0;
        C(j / 3, i / 3) += 1.0;
      }
      rhs2.col(pair) = vec(C);
    }
  }
  const Eigen::Matrix<double, 9, 45> d2S = sylvester.solve(rhs2);
  pair = 0;
  for (int j = 0; j < 9; ++j) {
    for (int i = 0; i <= j; ++i, ++pair) {
      const Vector9d d2S_ij = d2S.col(pair);
      const Eigen::Matrix3d d2R_ij = (-R * unvec(d2S_ij) - dR[j] * dS[i] - dR[i] * dS[j]) * S_inv;
      const Vector9d d2R_ij_vec = vec(d2R_ij);
      out.d2SdF2[j].col(i) = d2S_ij;
      out.d2SdF2[i].col(j) = d2S_ij;
      out.d2RdF2[j].col(i) = d2R_ij_vec;
      out.d2RdF2[i].col(j) = d2R_ij_vec;
    }
  }
  return out;
}

}  // namespace sinew::common
