#include "offline/linalg/singular_solver.hpp"

#include "offline/rigid/rigid_motion.hpp"

namespace sinew::offline {

RigidNullspaceSolver::RigidNullspaceSolver(const SparseCholeskyOptions& options)
    : cholesky_(options) {}

SparseCholeskyStatus RigidNullspaceSolver::factorise(const Eigen::SparseMatrix<double>& K,
                                                     const Eigen::Ref<const Eigen::VectorXd>& x) {
  if (K.rows() != K.cols() || K.rows() != x.size() || x.size() % 3 != 0) {
    return SparseCholeskyStatus::kInvalidInput;
  }
  const std::optional<std::array<Eigen::Index, 6>> pins = rigid_pin_dofs(x);
  if (!pins) return SparseCholeskyStatus::kInvalidInput;
  pins_ = *pins;
  nullspace_ = rigid_motion_basis(x);
  pinned_ = K;
  // The pinned rows get a diagonal of K's own magnitude, keeping the factor well scaled.
  const double diagonal = K.diagonal().cwiseAbs().mean();
  pin_dofs(pinned_, pins_, diagonal > 0.0 ? diagonal : 1.0);
  SparseCholeskyStatus status =
      cholesky_.analysed() ? cholesky_.factorise(pinned_) : SparseCholeskyStatus::kPatternMismatch;
  if (status == SparseCholeskyStatus::kPatternMismatch) status = cholesky_.compute(pinned_);
  return status;
}

SparseCholeskyStatus RigidNullspaceSolver::solve(const Eigen::Ref<const Eigen::MatrixXd>& rhs,
                                                 Eigen::MatrixXd& solution) {
  if (rhs.rows() != nullspace_.rows()) return SparseCholeskyStatus::kInvalidInput;
  Eigen::MatrixXd projected = rhs;
  projected.noalias() -= nullspace_ * (nullspace_.transpose() * rhs);
  for (Eigen::Index p : pins_) projected.row(p).setZero();
  solution.resize(rhs.rows(), rhs.cols());
  const SparseCholeskyStatus status = cholesky_.solve_in_blocks(projected, solution);
  if (status != SparseCholeskyStatus::kOk) return status;
  solution.noalias() -= nullspace_ * (nullspace_.transpose() * solution);
  return status;
}

}  // namespace sinew::offline
