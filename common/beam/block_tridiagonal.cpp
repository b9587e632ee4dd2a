#include "common/beam/block_tridiagonal.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <cmath>

namespace sinew::common {

void BlockTridiagonal::resize(int num_blocks) {
  diagonal_.assign(num_blocks, Eigen::Matrix3d::Zero());
  lower_.assign(num_blocks > 0 ? num_blocks - 1 : 0, Eigen::Matrix3d::Zero());
}

void BlockTridiagonal::set_zero() {
  for (auto& b : diagonal_) b.setZero();
  for (auto& b : lower_) b.setZero();
}

void BlockTridiagonal::add_element(int i, const Eigen::Matrix<double, 6, 6>& Ke) {
  diagonal_[i] += Ke.topLeftCorner<3, 3>();
  diagonal_[i + 1] += Ke.bottomRightCorner<3, 3>();
  lower_[i] += Ke.bottomLeftCorner<3, 3>();
}

void BlockTridiagonal::apply_fixed_dofs(const std::vector<unsigned char>& fixed) {
  const int n = num_blocks();
  for (int i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      if (!fixed[3 * i + a]) continue;
      diagonal_[i].row(a).setZero();
      diagonal_[i].col(a).setZero();
      diagonal_[i](a, a) = 1.0;
      if (i > 0) lower_[i - 1].row(a).setZero();  // row 3i+a, columns of block i-1
      if (i + 1 < n) lower_[i].col(a).setZero();  // column 3i+a, rows of block i+1
    }
  }
}

void BlockTridiagonal::multiply(const Eigen::Ref<const Eigen::VectorXd>& x,
                                Eigen::Ref<Eigen::VectorXd> y) const {
  const int n = num_blocks();
  for (int i = 0; i < n; ++i) {
    Eigen::Vector3d yi = diagonal_[i] * x.segment<3>(3 * i);
    if (i > 0) yi += lower_[i - 1] * x.segment<3>(3 * (i - 1));
    if (i + 1 < n) yi += lower_[i].transpose() * x.segment<3>(3 * (i + 1));
    y.segment<3>(3 * i) = yi;
  }
}

Eigen::MatrixXd BlockTridiagonal::to_dense() const {
  const int n = num_blocks();
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(3 * n, 3 * n);
  for (int i = 0; i < n; ++i) {
    A.block<3, 3>(3 * i, 3 * i) = diagonal_[i];
    if (i + 1 < n) {
      A.block<3, 3>(3 * (i + 1), 3 * i) = lower_[i];
      A.block<3, 3>(3 * i, 3 * (i + 1)) = lower_[i].transpose();
    }
  }
  return A;
}

void BlockTridiagonalLdlt::resize(int num_blocks) {
  pivot_inverse_.assign(num_blocks, Eigen::Matrix3d::Zero());
  pivot_.assign(num_blocks, Eigen::Matrix3d::Zero());
  multiplier_.assign(num_blocks, Eigen::Matrix3d::Zero());
}

bool BlockTridiagonalLdlt::factor(const BlockTridiagonal& A, double pivot_tolerance) {
  const int n = A.num_blocks();
  if (static_cast<int>(pivot_.size()) != n) return false;
  double scale = 0.0;
  for (int i = 0; i < n; ++i) scale = std::max(scale, A.diagonal(i).cwiseAbs().maxCoeff());
  if (!(scale > 0.0) || !std::isfinite(scale)) return false;

  for (int i = 0; i < n; ++i) {
    Eigen::Matrix3d S = A.diagonal(i);
    if (i > 0) {
      // L_i = A(i, i−1) S_{i−1}⁻¹ ;  S_i = A(i, i) − L_i A(i, i−1)ᵀ.
      multiplier_[i] = A.lower(i - 1) * pivot_inverse_[i - 1];
      S.noalias() -= multiplier_[i] * A.lower(i - 1).transpose();
    }
    S = 0.5 * (S + S.transpose()).eval();
    // Pivot check: 1/‖S⁻¹‖_F is within a factor √3 below the smallest |eigenvalue| of the
    // symmetric block, and costs no eigen-decomposition (the tracker factors every Newton step).
    pivot_[i] = S;
    pivot_inverse_[i] = S.inverse();
    const double inverse_norm = pivot_inverse_[i].norm();
    if (!std::isfinite(inverse_norm) || inverse_norm * pivot_tolerance * scale >= 1.0) return false;
  }
  return true;
}

void BlockTridiagonalLdlt::solve_in_place(Eigen::Ref<Eigen::VectorXd> b) const {
  const int n = static_cast<int>(pivot_.size());
  for (int i = 1; i < n; ++i) b.segment<3>(3 * i) -= multiplier_[i] * b.segment<3>(3 * (i - 1));
  for (int i = n - 1; i >= 0; --i) {
    Eigen::Vector3d xi = pivot_inverse_[i] * b.segment<3>(3 * i);
    if (i + 1 < n) xi -= multiplier_[i + 1].transpose() * b.segment<3>(3 * (i + 1));
    b.segment<3>(3 * i) = xi;
  }
}

int BlockTridiagonalLdlt::negative_eigenvalue_count() const {
  int count = 0;
  for (const auto& S : pivot_) {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
    eig.computeDirect(S, Eigen::EigenvaluesOnly);
    for (int k = 0; k < 3; ++k) count += eig.eigenvalues()[k] < 0.0 ? 1 : 0;
  }
  return count;
}

}  // namespace sinew::common
