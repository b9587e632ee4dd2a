// The block-tridiagonal LDLᵀ solve against Eigen's dense LU, on SPD and indefinite matrices, with
// fixed dofs, and its singularity report.
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include "common/beam/block_tridiagonal.hpp"
#include "tests/support/finite_difference.hpp"

namespace sinew::common {
namespace {

BlockTridiagonal random_matrix(int n, double shift, std::mt19937& gen) {
  BlockTridiagonal A(n);
  for (int i = 0; i < n; ++i) {
    Eigen::Matrix3d B =
        Eigen::Map<const Eigen::Matrix3d>(sinew::testing::random_vector(9, 1.0, gen).data());
    A.diagonal(i) = B + B.transpose() + shift * Eigen::Matrix3d::Identity();
    if (i + 1 < n) {
      A.lower(i) =
          Eigen::Map<const Eigen::Matrix3d>(sinew::testing::random_vector(9, 1.0, gen).data());
    }
  }
  return A;
}

TEST(BlockTridiagonal, SolveMatchesDense) {
  auto& gen = sinew::testing::rng();
  for (double shift : {8.0, 0.5}) {  // diagonally dominant SPD, then indefinite
    for (int n : {1, 2, 5, 40}) {
      const BlockTridiagonal A = random_matrix(n, shift, gen);
      const Eigen::MatrixXd dense = A.to_dense();
      const Eigen::VectorXd b = sinew::testing::random_vector(3 * n, 1.0, gen);
      BlockTridiagonalLdlt ldlt(n);
      ASSERT_TRUE(ldlt.factor(A));
      Eigen::VectorXd x = b;
      ldlt.solve_in_place(x);
      const Eigen::VectorXd x_dense = dense.fullPivLu().solve(b);
      EXPECT_LT((x - x_dense).norm(), 1e-9 * x_dense.norm()) << "n = " << n << " shift " << shift;
      Eigen::VectorXd Ax(3 * n);
      A.multiply(x, Ax);
      EXPECT_LT((Ax - b).norm(), 1e-9 * b.norm());
      if (shift > 4.0) {
        EXPECT_EQ(ldlt.negative_eigenvalue_count(), 0);
      } else {
        Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(dense);
        int negatives = 0;
        for (int k = 0; k < 3 * n; ++k) negatives += eig.eigenvalues()[k] < 0 ? 1 : 0;
        EXPECT_EQ(ldlt.negative_eigenvalue_count(), negatives);
      }
    }
  }
}

// add_element_lower is add_element given only the blocks the matrix stores: for a symmetric
// element matrix the two give the same matrix, bit for bit (the same additions).
TEST(BlockTridiagonal, AddingTheLowerBlocksOfAnElementEqualsAddingTheElement) {
  auto& gen = sinew::testing::rng();
  const int n = 4;
  BlockTridiagonal whole = random_matrix(n, 2.0, gen);
  BlockTridiagonal lower = whole;
  for (int i = 0; i + 1 < n; ++i) {
    Eigen::Matrix<double, 6, 6> Ke = Eigen::Map<const Eigen::Matrix<double, 6, 6>>(
        sinew::testing::random_vector(36, 1.0, gen).data());
    Ke = (Ke + Ke.transpose()).eval();
    whole.add_element(i, Ke);
    const Eigen::Matrix<double, 6, 3> left = Ke.leftCols<3>();
    lower.add_element_lower(i, left, Ke.bottomRightCorner<3, 3>());
  }
  EXPECT_EQ(whole.to_dense(), lower.to_dense());
}

TEST(BlockTridiagonal, ColumnsSolvedTogetherEqualColumnsSolvedAlone) {
  auto& gen = sinew::testing::rng();
  for (double shift : {8.0, 0.5}) {
    for (int n : {1, 3, 65}) {
      const BlockTridiagonal A = random_matrix(n, shift, gen);
      BlockTridiagonalLdlt ldlt(n);
      ASSERT_TRUE(ldlt.factor(A));
      Eigen::MatrixXd B(3 * n, 4);
      for (int c = 0; c < 4; ++c) B.col(c) = sinew::testing::random_vector(3 * n, 1.0, gen);
      Eigen::MatrixXd X = B;
      ldlt.solve_columns_in_place(X.leftCols(3));  // the last column stays as it was
      for (int c = 0; c < 3; ++c) {
        Eigen::VectorXd x = B.col(c);
        ldlt.solve_in_place(x);
        // The same operations in the same order (equal unless a compiler contracts them
        // differently).
        EXPECT_LE((X.col(c) - x).norm(), 1e-14 * x.norm()) << "n = " << n << " column " << c;
      }
      EXPECT_EQ((X.col(3) - B.col(3)).cwiseAbs().maxCoeff(), 0.0);
    }
  }
}

TEST(BlockTridiagonal, FixedDofsGiveIdentityRows) {
  auto& gen = sinew::testing::rng();
  BlockTridiagonal A = random_matrix(4, 8.0, gen);
  std::vector<unsigned char> fixed(12, 0);
  fixed[0] = fixed[4] = fixed[11] = 1;
  A.apply_fixed_dofs(fixed);
  const Eigen::MatrixXd dense = A.to_dense();
  for (int k : {0, 4, 11}) {
    Eigen::VectorXd e = Eigen::VectorXd::Unit(12, k);
    EXPECT_EQ((dense.row(k).transpose() - e).norm(), 0.0);
    EXPECT_EQ((dense.col(k) - e).norm(), 0.0);
  }
}

TEST(BlockTridiagonal, ReportsSingularMatrix) {
  BlockTridiagonal A(3);
  for (int i = 0; i < 3; ++i) A.diagonal(i) = Eigen::Matrix3d::Identity();
  A.diagonal(1)(2, 2) = 0.0;
  BlockTridiagonalLdlt ldlt(3);
  EXPECT_FALSE(ldlt.factor(A));
}

}  // namespace
}  // namespace sinew::common
