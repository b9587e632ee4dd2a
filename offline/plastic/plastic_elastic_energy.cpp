#include "offline/plastic/plastic_elastic_energy.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <sstream>

namespace sinew::offline {

namespace {

using common::Matrix12d;
using common::Matrix3x4d;
using common::Matrix9d;
using common::Matrix9x12d;
using common::unvec;
using common::vec;
using common::Vector12d;
using common::Vector9d;

void fill_nan(const PlasticTetOutputs& out) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (out.energy) *out.energy = nan;
  if (out.gradient_x) out.gradient_x->setConstant(nan);
  if (out.gradient_s) out.gradient_s->setConstant(nan);
  if (out.hessian_xx) out.hessian_xx->setConstant(nan);
  if (out.hessian_xs) out.hessian_xs->setConstant(nan);
  if (out.hessian_ss) out.hessian_ss->setConstant(nan);
}

Matrix3x4d rest_tet(const Eigen::Ref<const Eigen::MatrixXd>& rest_positions,
                    const common::TetIndices& tets, Eigen::Index t) {
  Matrix3x4d X;
  for (int a = 0; a < 4; ++a) X.col(a) = rest_positions.row(tets(t, a)).transpose();
  return X;
}

}  // namespace

common::Matrix9x12d elastic_deformation_gradient_jacobian(const common::Tet4Rest& rest,
                                                          const Eigen::Matrix3d& Fp_inv) {
  return common::deformation_gradient_jacobian(
      common::shape_gradients_from_Dm_inv(rest.Dm_inv * Fp_inv));
}

PlasticStrainStatus evaluate_plastic_tet(const common::StableNeoHookean& material,
                                         const common::Tet4Rest& rest, const Vector6d& s,
                                         const common::Matrix3x4d& positions,
                                         const PlasticTetOutputs& out,
                                         common::HessianProjection projection) {
  const bool need_s_derivatives = out.gradient_s || out.hessian_xs || out.hessian_ss;
  const PlasticDerivativeOrder order = out.hessian_ss       ? PlasticDerivativeOrder::kSecond
                                       : need_s_derivatives ? PlasticDerivativeOrder::kFirst
                                                            : PlasticDerivativeOrder::kValue;
  const PlasticStrainDerivatives p = plastic_strain_derivatives(s, order);
  if (!p.invertible()) {
    fill_nan(out);
    return p.status;
  }
  if (!positions.allFinite()) {
    fill_nan(out);
    return PlasticStrainStatus::kNonFinite;
  }

  const double V0 = std::abs(rest.volume);
  const double V = p.det * V0;  // eq. 1: plastic rest volume
  const Eigen::Matrix3d F = common::deformation_gradient(rest, positions);
  const Eigen::Matrix3d Fe = F * p.Fp_inv;

  const bool need_psi = out.energy || out.gradient_s || out.hessian_ss;
  const bool need_P = out.gradient_x || need_s_derivatives;
  const bool need_dPdF = out.hessian_xx || out.hessian_xs || out.hessian_ss;
  const bool need_Be = out.gradient_x || out.hessian_xx || out.hessian_xs;

  const double psi = need_psi ? material.psi(Fe) : 0.0;
  const Vector9d P = need_P ? vec(material.P(Fe)) : Vector9d::Zero();
  const Matrix9d dPdF = need_dPdF ? material.dPdF(Fe) : Matrix9d::Zero();
  const Matrix9x12d Be =
      need_Be ? elastic_deformation_gradient_jacobian(rest, p.Fp_inv) : Matrix9x12d::Zero();

  // G = ∂vec(Fe)/∂s (9x6): column k = vec(F ∂Fp⁻¹/∂s_k) (eq. 34, times Y); dV = ∂V/∂s (eq. 35).
  Matrix9x6d G = Matrix9x6d::Zero();
  Vector6d dV = Vector6d::Zero();
  if (need_s_derivatives) {
    for (int k = 0; k < kPlasticStrainSize; ++k) G.col(k) = vec(F * unvec(p.dFp_inv_ds.col(k)));
    dV = V0 * p.ddet_ds;
  }

  if (out.energy) *out.energy = V * psi;
  if (out.gradient_x) out.gradient_x->noalias() = V * Be.transpose() * P;  // eq. 32
  // ∂ψ/∂s = Gᵀ vec(P); eq. 33: ∂E/∂s = V ∂ψ/∂s + ψ ∂V/∂s.
  const Vector6d dpsi_ds = need_s_derivatives ? Vector6d(G.transpose() * P) : Vector6d::Zero();
  if (out.gradient_s) *out.gradient_s = V * dpsi_ds + psi * dV;

  if (out.hessian_xx) {  // eq. 36
    Matrix9d C = dPdF;
    if (projection == common::HessianProjection::kProjectDPdF) C = common::project_to_psd(C);
    const Matrix9x12d C_Be = C * Be;
    out.hessian_xx->noalias() = V * Be.transpose() * C_Be;
    if (projection == common::HessianProjection::kProjectElement) {
      *out.hessian_xx = common::project_to_psd(Matrix12d(*out.hessian_xx));
    }
  }

  if (out.hessian_xs) {  // eqs. 37–39
    // ∂Be/∂s_k = ((∂Fp⁻¹/∂s_k)ᵀ ⊗ I₃)·dFdx, so (∂Be/∂s_k)ᵀ vec(P) = dFdxᵀ vec(P (∂Fp⁻¹/∂s_k)ᵀ).
    Matrix9x6d P_dFp_inv;
    for (int k = 0; k < kPlasticStrainSize; ++k) {
      P_dFp_inv.col(k) = vec(unvec(P) * unvec(p.dFp_inv_ds.col(k)).transpose());
    }
    const Vector12d Be_P = Be.transpose() * P;
    const Matrix9x6d dPdF_G = dPdF * G;
    Matrix12x6d& H = *out.hessian_xs;
    H.noalias() = Be_P * dV.transpose();
    H.noalias() += V * rest.dFdx.transpose() * P_dFp_inv;
    H.noalias() += V * Be.transpose() * dPdF_G;
  }

  if (out.hessian_ss) {  // eqs. 40–44
    // P : (F ∂²Fp⁻¹/∂s_k∂s_l) = vec(FᵀP) · vec(∂²Fp⁻¹/∂s_k∂s_l).
    const Vector9d FtP = vec(F.transpose() * unvec(P));
    Matrix6d T;
    for (int l = 0; l < kPlasticStrainSize; ++l) {
      T.col(l) = p.d2Fp_inv_ds2[static_cast<std::size_t>(l)].transpose() * FtP;
    }
    const Matrix9x6d dPdF_G = dPdF * G;
    Matrix6d& H = *out.hessian_ss;
    H.noalias() = (psi * V0) * p.d2det_ds2;
    H.noalias() += dV * dpsi_ds.transpose();
    H.noalias() += dpsi_ds * dV.transpose();
    H.noalias() += V * G.transpose() * dPdF_G;
    H.noalias() += V * T;
  }
  return p.status;
}

std::optional<std::string> PlasticElasticEnergyOptions::validate() const {
  if (!(degeneracy_tolerance >= 0.0 && degeneracy_tolerance < 0.1)) {
    std::ostringstream s;
    s << "degeneracy_tolerance = " << degeneracy_tolerance << " must be in [0, 0.1)";
    return s.str();
  }
  return std::nullopt;
}

const char* to_string(PlasticEvaluationStatus status) {
  switch (status) {
    case PlasticEvaluationStatus::kOk:
      return "ok";
    case PlasticEvaluationStatus::kNotPositiveDefinite:
      return "plastic strain not positive definite";
    case PlasticEvaluationStatus::kSingularPlasticStrain:
      return "singular plastic strain";
    case PlasticEvaluationStatus::kNonFinite:
      return "non-finite input or result";
    case PlasticEvaluationStatus::kInvalidSize:
      return "s is not 6m or x is not 3n";
  }
  return "unknown";
}

std::string PlasticEvaluation::message() const {
  std::ostringstream s;
  s << to_string(status);
  if (tet) s << " (tet " << *tet << ")";
  return s.str();
}

std::optional<PlasticElasticEnergy> PlasticElasticEnergy::create(
    const Eigen::Ref<const Eigen::MatrixXd>& rest_positions, const common::TetIndices& tets,
    const common::StableNeoHookean& material, const PlasticElasticEnergyOptions& options,
    common::TetMeshCheck* check) {
  common::TetMeshCheck result;
  if (options.validate()) {
    result.status = common::TetMeshStatus::kInvalidOptions;
  } else {
    result = common::check_tet_mesh(rest_positions, tets, options.degeneracy_tolerance);
  }
  if (check) *check = result;
  if (!result.ok()) return std::nullopt;

  PlasticElasticEnergy mesh(material, options);
  const Eigen::Index n = rest_positions.rows();
  const Eigen::Index m = tets.rows();
  mesh.num_vertices_ = n;
  mesh.tets_ = tets;
  mesh.rest_dofs_ = common::to_dof_vector(rest_positions);
  mesh.rest_.reserve(static_cast<std::size_t>(m));
  for (Eigen::Index t = 0; t < m; ++t) {
    mesh.rest_.push_back(
        common::make_tet4_rest(rest_tet(rest_positions, tets, t), options.degeneracy_tolerance));
  }
  if (mesh.assembly_.analyse(tets, n, options.storage) != common::AssemblyStatus::kOk) {
    if (check) *check = {common::TetMeshStatus::kIndexOutOfRange, mesh.assembly_.bad_element()};
    return std::nullopt;
  }

  // ∂f_e/∂s: column 6t+k holds the 12 dofs of tet t's vertices in increasing vertex order (the
  // four vertices are distinct: check_tet_mesh rejected degenerate tets).
  using StorageIndex = Eigen::SparseMatrix<double>::StorageIndex;
  constexpr int kEntries = 12;
  const Eigen::Index cols = kPlasticStrainSize * m;
  std::vector<StorageIndex> outer(static_cast<std::size_t>(cols) + 1);
  std::vector<StorageIndex> inner(static_cast<std::size_t>(cols) * kEntries);
  mesh.force_jacobian_scatter_.resize(m, 4);
  for (Eigen::Index t = 0; t < m; ++t) {
    std::array<int, 4> order = {0, 1, 2, 3};
    std::sort(order.begin(), order.end(), [&](int a, int b) { return tets(t, a) < tets(t, b); });
    for (int r = 0; r < 4; ++r)
      mesh.force_jacobian_scatter_(t, order[static_cast<std::size_t>(r)]) = 3 * r;
    for (int k = 0; k < kPlasticStrainSize; ++k) {
      const Eigen::Index col = kPlasticStrainSize * t + k;
      StorageIndex* rows = inner.data() + col * kEntries;
      for (int r = 0; r < 4; ++r) {
        for (int d = 0; d < 3; ++d) {
          rows[3 * r + d] =
              static_cast<StorageIndex>(3 * tets(t, order[static_cast<std::size_t>(r)]) + d);
        }
      }
    }
  }
  for (Eigen::Index c = 0; c <= cols; ++c) {
    outer[static_cast<std::size_t>(c)] = static_cast<StorageIndex>(c * kEntries);
  }
  std::vector<double> values(inner.size(), 0.0);
  mesh.force_jacobian_ = Eigen::Map<const Eigen::SparseMatrix<double>>(
      3 * n, cols, static_cast<Eigen::Index>(inner.size()), outer.data(), inner.data(),
      values.data());
  mesh.force_jacobian_.makeCompressed();

  mesh.gradient_x_ = Eigen::VectorXd::Zero(3 * n);
  mesh.gradient_s_ = Eigen::VectorXd::Zero(cols);
  return mesh;
}

common::Matrix3x4d PlasticElasticEnergy::tet_positions(
    Eigen::Index t, const Eigen::Ref<const Eigen::VectorXd>& x) const {
  Matrix3x4d positions;
  for (int a = 0; a < 4; ++a) positions.col(a) = x.segment<3>(3 * tets_(t, a));
  return positions;
}

PlasticEvaluation PlasticElasticEnergy::evaluate(const Eigen::Ref<const Eigen::VectorXd>& s,
                                                 const Eigen::Ref<const Eigen::VectorXd>& x,
                                                 const PlasticEnergyRequest& request) {
  PlasticEvaluation result;
  if (s.size() != num_plastic_dofs() || x.size() != num_dofs()) return result;
  result.status = PlasticEvaluationStatus::kOk;
  if (!s.allFinite() || !x.allFinite()) {
    result.status = PlasticEvaluationStatus::kNonFinite;
    return result;
  }

  double element_energy = 0.0;
  Vector12d element_gradient_x;
  Vector6d element_gradient_s;
  Matrix12d element_hessian_xx;
  Matrix12x6d element_hessian_xs;
  PlasticTetOutputs outputs;
  if (request.energy) outputs.energy = &element_energy;
  if (request.gradient_x) outputs.gradient_x = &element_gradient_x;
  if (request.gradient_s) outputs.gradient_s = &element_gradient_s;
  if (request.stiffness) outputs.hessian_xx = &element_hessian_xx;
  if (request.force_jacobian) outputs.hessian_xs = &element_hessian_xs;

  if (request.energy) energy_ = 0.0;
  if (request.gradient_x) gradient_x_.setZero();
  if (request.stiffness) assembly_.set_zero();
  double* force_jacobian_values = force_jacobian_.valuePtr();

  for (Eigen::Index t = 0; t < num_tets(); ++t) {
    const PlasticStrainStatus status =
        evaluate_plastic_tet(material_, rest_[static_cast<std::size_t>(t)],
                             s.segment<kPlasticStrainSize>(kPlasticStrainSize * t),
                             tet_positions(t, x), outputs, options_.projection);
    if (status == PlasticStrainStatus::kSingular || status == PlasticStrainStatus::kNonFinite) {
      result.status = status == PlasticStrainStatus::kSingular
                          ? PlasticEvaluationStatus::kSingularPlasticStrain
                          : PlasticEvaluationStatus::kNonFinite;
      result.tet = t;
      return result;
    }
    if (status == PlasticStrainStatus::kNotPositiveDefinite &&
        result.status == PlasticEvaluationStatus::kOk) {
      result.status = PlasticEvaluationStatus::kNotPositiveDefinite;
      result.tet = t;
    }
    if (request.energy) energy_ += element_energy;
    if (request.gradient_x) assembly_.add_element_vector(t, element_gradient_x, gradient_x_);
    if (request.gradient_s) {
      gradient_s_.segment<kPlasticStrainSize>(kPlasticStrainSize * t) = element_gradient_s;
    }
    if (request.stiffness) assembly_.add_element_matrix(t, element_hessian_xx);
    if (request.force_jacobian) {
      for (int k = 0; k < kPlasticStrainSize; ++k) {
        double* column = force_jacobian_values + 12 * (kPlasticStrainSize * t + k);
        for (int a = 0; a < 4; ++a) {
          const int offset = force_jacobian_scatter_(t, a);
          for (int d = 0; d < 3; ++d) column[offset + d] = element_hessian_xs(3 * a + d, k);
        }
      }
    }
  }
  if (request.energy && !std::isfinite(energy_)) {
    result.status = PlasticEvaluationStatus::kNonFinite;
    result.tet.reset();
  }
  return result;
}

}  // namespace sinew::offline
