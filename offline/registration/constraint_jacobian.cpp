#include "offline/registration/constraint_jacobian.hpp"

#include <Eigen/LU>
#include <cmath>
#include <utility>

#include "offline/detail/column_blocks.hpp"
#include "offline/detail/huge_pages.hpp"
#include "offline/rigid/rigid_motion.hpp"

namespace sinew::offline {
namespace {

// The weighted constraint rows [√c_k A_k] (r x 3n, sparse) and the residual [√c_k (A_k x + b_k)].
struct WeightedRows {
  Eigen::SparseMatrix<double> rows;
  Eigen::VectorXd residual;
};

WeightedRows weighted_rows(const PointConstraints& terms,
                           const Eigen::Ref<const Eigen::VectorXd>& x) {
  const Eigen::Index r = 3 * terms.size();
  WeightedRows result;
  Eigen::VectorXd sqrt_c(r);
  result.residual.resize(r);
  for (Eigen::Index k = 0; k < terms.size(); ++k) {
    const double root = std::sqrt(terms.weight(k));
    sqrt_c.segment<3>(3 * k).setConstant(root);
    result.residual.segment<3>(3 * k) = root * terms.residual(k, x);
  }
  result.rows = sqrt_c.asDiagonal() * terms.stacked_selection();
  return result;
}

// Zᵀ = −(∂f/∂s)ᵀ W, one column of W at a time: Eigen's row-major sparse × dense product walks
// rows of W (stride 3n) for all r columns at once, which is cache-hostile when W is 3n x 900.
// Columns are independent: blocks of them go to the available threads. Zᵀ (6m x r, 1.3 GB at
// 30k tets and 900 rows) is backed by huge pages.
Eigen::MatrixXd z_transposed(const Eigen::SparseMatrix<double>& force_jacobian,
                             const Eigen::MatrixXd& W, Eigen::MatrixXd* storage) {
  Eigen::MatrixXd Zt;
  if (storage != nullptr && storage->rows() == force_jacobian.cols() &&
      storage->cols() == W.cols()) {
    Zt = std::move(*storage);
  } else {
    Zt = detail::large_matrix(force_jacobian.cols(), W.cols());
  }
  detail::for_each_column_block(W.cols(), 8, detail::available_threads(),
                                [&](int /*thread*/, Eigen::Index first, Eigen::Index k) {
                                  for (Eigen::Index j = first; j < first + k; ++j) {
                                    Zt.col(j).noalias() = -(force_jacobian.transpose() * W.col(j));
                                  }
                                });
  return Zt;
}

bool evaluate_tangent(PlasticElasticEnergy& energy, const Eigen::Ref<const Eigen::VectorXd>& s,
                      const Eigen::Ref<const Eigen::VectorXd>& x, std::string* why) {
  PlasticEnergyRequest request;
  request.energy = false;
  request.stiffness = true;
  request.force_jacobian = true;
  const PlasticEvaluation evaluation = energy.evaluate(s, x, request);
  if (!evaluation.valid() && why != nullptr) *why = "tangent stiffness: " + evaluation.message();
  return evaluation.valid();
}

}  // namespace

std::optional<ConstraintJacobian> constraint_jacobian(
    PlasticElasticEnergy& energy, const PointConstraints& springs, const PointConstraints& terms,
    const Eigen::Ref<const Eigen::VectorXd>& s, const Eigen::Ref<const Eigen::VectorXd>& x,
    SparseCholesky& tangent, std::string* why, Eigen::MatrixXd* storage) {
  auto fail = [&](const std::string& message) -> std::optional<ConstraintJacobian> {
    if (why != nullptr) *why = message;
    return std::nullopt;
  };
  if (!evaluate_tangent(energy, s, x, why)) return std::nullopt;
  // ∂f_net/∂x = K + Σ_attachments c A_kᵀA_k.
  const Eigen::SparseMatrix<double> tangent_stiffness = energy.stiffness() + springs.hessian();
  SparseCholeskyStatus status = tangent.analysed() ? tangent.factorise(tangent_stiffness)
                                                   : SparseCholeskyStatus::kPatternMismatch;
  if (status == SparseCholeskyStatus::kPatternMismatch) status = tangent.compute(tangent_stiffness);
  if (status != SparseCholeskyStatus::kOk) {
    return fail(std::string("tangent stiffness at the equilibrium: ") + to_string(status));
  }
  // Z = −(√c A) K⁻¹ ∂f/∂s (eq. 12), through W = K⁻¹ (√c A)ᵀ (3n x 3K, one block solve): the
  // paper's "∂f_net/∂x z̃_k = −√c_k A_kᵀ", J never formed.
  WeightedRows rows = weighted_rows(terms, x);
  const Eigen::MatrixXd rhs = Eigen::MatrixXd(rows.rows.transpose());
  Eigen::MatrixXd W = detail::large_matrix(rhs.rows(), rhs.cols());
  if (tangent.solve_in_blocks(rhs, W) != SparseCholeskyStatus::kOk) {
    return fail("tangent solve failed");
  }
  return ConstraintJacobian{z_transposed(energy.force_jacobian(), W, storage),
                            std::move(rows.residual)};
}

std::optional<ConstraintJacobian> free_constraint_jacobian(
    PlasticElasticEnergy& energy, const PointConstraints& terms,
    const RigidStabilisation& stabilisation, const RigidFrame& frame,
    const Eigen::Ref<const Eigen::VectorXd>& s, const Eigen::Ref<const Eigen::VectorXd>& x,
    RigidNullspaceSolver& tangent, std::string* why, Eigen::MatrixXd* storage) {
  auto fail = [&](const std::string& message) -> std::optional<ConstraintJacobian> {
    if (why != nullptr) *why = message;
    return std::nullopt;
  };
  if (!evaluate_tangent(energy, s, x, why)) return std::nullopt;
  const SparseCholeskyStatus status = tangent.factorise(energy.stiffness(), x);
  if (status != SparseCholeskyStatus::kOk) {
    return fail(std::string("pinned tangent stiffness at the free equilibrium: ") +
                to_string(status));
  }
  StabilisationJacobian G;
  if (!stabilisation.jacobian(x, frame, G)) {
    return fail("stabilisation constraints: the marker points' covariance is singular or mirrored");
  }
  // The equilibrium moves with s as dx = P·K⁺(−∂f/∂s ds): K⁺ by the Singular Lemma (ii), and
  // P = I − Ψ(GΨ)⁻¹G adds the rigid motion that keeps eqs. 19–20 satisfied (G dx = 0). So
  // Zᵀ = −(∂f/∂s)ᵀ K⁺ Pᵀ(√c A)ᵀ, and Pᵀ(√c A)ᵀ lies in the range of K (Ψᵀ Pᵀ = (PΨ)ᵀ = 0).
  const Eigen::Matrix<double, Eigen::Dynamic, 6> psi = rigid_motion_basis(x, false);
  const Eigen::Matrix<double, 6, 6> G_psi = G * psi;
  Eigen::FullPivLU<Eigen::Matrix<double, 6, 6>> lu(G_psi);
  if (!lu.isInvertible()) return fail("stabilisation constraints do not fix the rigid motions");
  WeightedRows rows = weighted_rows(terms, x);
  Eigen::MatrixXd rhs = Eigen::MatrixXd(rows.rows.transpose());
  const Eigen::MatrixXd psi_t_rhs = psi.transpose() * rhs;  // 6 x r
  rhs.noalias() -= G.transpose() * G_psi.transpose().fullPivLu().solve(psi_t_rhs);
  Eigen::MatrixXd W;
  if (tangent.solve(rhs, W) != SparseCholeskyStatus::kOk) return fail("tangent solve failed");
  return ConstraintJacobian{z_transposed(energy.force_jacobian(), W, storage),
                            std::move(rows.residual)};
}

}  // namespace sinew::offline
