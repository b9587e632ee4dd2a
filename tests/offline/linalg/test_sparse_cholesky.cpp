// Tests of offline/sparse_cholesky: CHOLMOD's LLᵀ (simplicial by default; the supernodal method
// against it) against Eigen's SimplicialLDLT on a random SPD matrix and on a box-mesh Laplacian
// plus a shift (full and upper storage), a block of right-hand sides against column-by-column
// solves, refactorisation with new values on the analysed pattern, and the statuses for a matrix
// that is not positive definite, a different pattern and out-of-order calls.

#include "offline/linalg/sparse_cholesky.hpp"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <random>
#include <thread>
#include <vector>

#include "tests/support/finite_difference.hpp"
#include "tests/support/tet_mesh_fixtures.hpp"

namespace sinew::offline {
namespace {

using SparseMatrix = Eigen::SparseMatrix<double>;

// A = BᵀB + I for a random sparse B (n x n, about 4 entries per column): SPD, full storage.
SparseMatrix random_spd(int n, std::mt19937& gen) {
  std::uniform_int_distribution<int> row(0, n - 1);
  std::uniform_real_distribution<double> value(-1.0, 1.0);
  std::vector<Eigen::Triplet<double>> triplets;
  for (int c = 0; c < n; ++c) {
    for (int k = 0; k < 4; ++k) triplets.emplace_back(row(gen), c, value(gen));
  }
  SparseMatrix B(n, n);
  B.setFromTriplets(triplets.begin(), triplets.end());
  SparseMatrix I(n, n);
  I.setIdentity();
  SparseMatrix A = SparseMatrix(B.transpose()) * B + I;
  A.makeCompressed();
  return A;
}

// Graph Laplacian of the vertex adjacency of a box tet mesh plus shift·I (full storage).
SparseMatrix box_laplacian(double shift) {
  const testing::TetMesh mesh = testing::make_box_mesh(5, 4, 3, 0.1);
  const auto n = static_cast<int>(mesh.rest_positions.rows());
  std::vector<Eigen::Triplet<double>> triplets;
  for (Eigen::Index t = 0; t < mesh.tets.rows(); ++t) {
    for (int a = 0; a < 4; ++a) {
      for (int b = 0; b < 4; ++b) {
        if (a == b) continue;
        // Each edge is shared by several tets: weight 1 per tet, still a Laplacian.
        triplets.emplace_back(mesh.tets(t, a), mesh.tets(t, b), -1.0);
        triplets.emplace_back(mesh.tets(t, a), mesh.tets(t, a), 1.0);
      }
    }
  }
  for (int i = 0; i < n; ++i) triplets.emplace_back(i, i, shift);
  SparseMatrix A(n, n);
  A.setFromTriplets(triplets.begin(), triplets.end());
  A.makeCompressed();
  return A;
}

SparseMatrix upper_of(const SparseMatrix& A) {
  SparseMatrix U = A.triangularView<Eigen::Upper>();
  U.makeCompressed();
  return U;
}

Eigen::MatrixXd reference_solve(const SparseMatrix& A, const Eigen::MatrixXd& B) {
  Eigen::SimplicialLDLT<SparseMatrix> ldlt(A);
  EXPECT_EQ(ldlt.info(), Eigen::Success);
  return ldlt.solve(B);
}

double relative_difference(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return (a - b).norm() / b.norm();
}

TEST(SparseCholesky, RandomSpdMatchesSimplicialLdlt) {
  std::mt19937 gen(7);
  const SparseMatrix A = random_spd(120, gen);
  const Eigen::VectorXd b = testing::random_vector(A.rows(), 1.0, gen);
  for (const SparseCholeskyOrdering ordering :
       {SparseCholeskyOrdering::kMetis, SparseCholeskyOrdering::kAmd,
        SparseCholeskyOrdering::kCholmod}) {
    SparseCholesky cholesky(SparseCholeskyOptions{ordering});
    ASSERT_EQ(cholesky.compute(A), SparseCholeskyStatus::kOk) << to_string(ordering);
    Eigen::VectorXd x(A.rows());
    ASSERT_EQ(cholesky.solve(b, x), SparseCholeskyStatus::kOk);
    EXPECT_LT(relative_difference(x, reference_solve(A, b)), 1e-10) << to_string(ordering);
    EXPECT_LT((A * x - b).norm(), 1e-10 * b.norm());
    ASSERT_TRUE(cholesky.factor_nonzeros().has_value());
    EXPECT_GE(*cholesky.factor_nonzeros(), static_cast<double>(A.rows()));
    EXPECT_GE(cholesky.factorisation_seconds(), 0.0);
    EXPECT_EQ(cholesky.num_factorisations(), 1);
    ASSERT_TRUE(cholesky.ordering_used().has_value());
  }
}

TEST(SparseCholesky, BoxLaplacianPlusShiftFullAndUpperStorage) {
  const SparseMatrix A = box_laplacian(0.05);
  std::mt19937 gen(11);
  const Eigen::VectorXd b = testing::random_vector(A.rows(), 1.0, gen);
  const Eigen::VectorXd reference = reference_solve(A, b);

  for (const SparseMatrix& stored : {A, upper_of(A)}) {
    SparseCholesky cholesky;
    ASSERT_EQ(cholesky.compute(stored), SparseCholeskyStatus::kOk);
    Eigen::VectorXd x(A.rows());
    ASSERT_EQ(cholesky.solve(b, x), SparseCholeskyStatus::kOk);
    EXPECT_LT(relative_difference(x, reference), 1e-10);
  }
  // METIS on a 3D mesh: less fill than AMD is typical, but both must be sane.
  SparseCholesky metis(SparseCholeskyOptions{SparseCholeskyOrdering::kMetis});
  ASSERT_EQ(metis.analyse(A), SparseCholeskyStatus::kOk);
  EXPECT_EQ(metis.ordering_used().value_or(""), "metis");
  EXPECT_LT(*metis.factor_nonzeros(), static_cast<double>(A.rows()) * A.rows());
}

TEST(SparseCholesky, BlockOfRightHandSidesEqualsColumnByColumn) {
  std::mt19937 gen(3);
  const SparseMatrix A = box_laplacian(0.2);
  Eigen::MatrixXd B(A.rows(), 9);
  for (Eigen::Index j = 0; j < B.cols(); ++j) B.col(j) = testing::random_vector(A.rows(), 1.0, gen);

  SparseCholesky cholesky;
  ASSERT_EQ(cholesky.compute(A), SparseCholeskyStatus::kOk);
  Eigen::MatrixXd X(A.rows(), B.cols());
  ASSERT_EQ(cholesky.solve(B, X), SparseCholeskyStatus::kOk);
  for (Eigen::Index j = 0; j < B.cols(); ++j) {
    Eigen::VectorXd x(A.rows());
    ASSERT_EQ(cholesky.solve(B.col(j), x), SparseCholeskyStatus::kOk);
    EXPECT_LT((X.col(j) - x).norm(), 1e-12 * x.norm()) << "column " << j;
  }
  EXPECT_LT(relative_difference(X, reference_solve(A, B)), 1e-10);
  // A block whose size does not match is refused.
  Eigen::MatrixXd wrong(A.rows(), 3);
  EXPECT_EQ(cholesky.solve(B, wrong), SparseCholeskyStatus::kInvalidInput);
}

TEST(SparseCholesky, ThreadsWithTheirOwnWorkspacesShareOneFactor) {
  // Four threads solve different column blocks with one factor at once, each with its own
  // workspace, many times over: every block equals the single-threaded solve.
  std::mt19937 gen(4);
  const SparseMatrix A = box_laplacian(0.2);
  Eigen::MatrixXd B(A.rows(), 16);
  for (Eigen::Index j = 0; j < B.cols(); ++j) B.col(j) = testing::random_vector(A.rows(), 1.0, gen);
  SparseCholesky cholesky;
  ASSERT_EQ(cholesky.compute(A), SparseCholeskyStatus::kOk);
  Eigen::MatrixXd serial(A.rows(), B.cols());
  ASSERT_EQ(cholesky.solve(B, serial), SparseCholeskyStatus::kOk);

  Eigen::MatrixXd parallel = Eigen::MatrixXd::Zero(A.rows(), B.cols());
  std::vector<SparseCholeskyStatus> statuses(4, SparseCholeskyStatus::kOk);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&, t] {
      SparseCholesky::SolveWorkspace workspace;
      Eigen::MatrixXd X(A.rows(), 4);
      for (int repeat = 0; repeat < 50; ++repeat) {
        const SparseCholeskyStatus status = static_cast<const SparseCholesky&>(cholesky).solve(
            B.middleCols(4 * t, 4), X, workspace);
        if (status != SparseCholeskyStatus::kOk) statuses[static_cast<std::size_t>(t)] = status;
      }
      parallel.middleCols(4 * t, 4) = X;
    });
  }
  for (std::thread& thread : threads) thread.join();
  for (const SparseCholeskyStatus status : statuses) EXPECT_EQ(status, SparseCholeskyStatus::kOk);
  EXPECT_LT(relative_difference(parallel, serial), 1e-12);
}

TEST(SparseCholesky, RefactorisesNewValuesOnTheAnalysedPattern) {
  std::mt19937 gen(5);
  SparseMatrix A = random_spd(80, gen);
  const Eigen::VectorXd b = testing::random_vector(A.rows(), 1.0, gen);
  SparseCholesky cholesky;
  ASSERT_EQ(cholesky.analyse(A), SparseCholeskyStatus::kOk);
  EXPECT_FALSE(cholesky.factorised());

  for (int round = 0; round < 3; ++round) {
    // New values, same pattern: scale and shift the diagonal.
    for (Eigen::Index c = 0; c < A.outerSize(); ++c) {
      for (SparseMatrix::InnerIterator it(A, c); it; ++it) {
        it.valueRef() *= 1.5;
        if (it.row() == it.col()) it.valueRef() += 0.3 * (round + 1);
      }
    }
    ASSERT_EQ(cholesky.factorise(A), SparseCholeskyStatus::kOk);
    Eigen::VectorXd x(A.rows());
    ASSERT_EQ(cholesky.solve(b, x), SparseCholeskyStatus::kOk);
    EXPECT_LT(relative_difference(x, reference_solve(A, b)), 1e-10) << "round " << round;
  }
  EXPECT_EQ(cholesky.num_factorisations(), 3);
  EXPECT_GE(cholesky.total_factorisation_seconds(), cholesky.factorisation_seconds());

  // Another pattern is refused (the analysis is not redone silently).
  const SparseMatrix other = box_laplacian(1.0);
  EXPECT_EQ(cholesky.factorise(other), SparseCholeskyStatus::kPatternMismatch);
}

TEST(SparseCholesky, NotPositiveDefiniteIsAStatusWithTheFailedColumn) {
  // Diagonally dominant tridiagonal matrix with one negative diagonal entry at column 17.
  const int n = 40;
  const int bad = 17;
  std::vector<Eigen::Triplet<double>> triplets;
  for (int i = 0; i < n; ++i) {
    triplets.emplace_back(i, i, i == bad ? -4.0 : 4.0);
    if (i + 1 < n) {
      triplets.emplace_back(i, i + 1, -1.0);
      triplets.emplace_back(i + 1, i, -1.0);
    }
  }
  SparseMatrix A(n, n);
  A.setFromTriplets(triplets.begin(), triplets.end());
  A.makeCompressed();

  SparseCholesky cholesky;
  ASSERT_EQ(cholesky.analyse(A), SparseCholeskyStatus::kOk);
  EXPECT_EQ(cholesky.factorise(A), SparseCholeskyStatus::kNotPositiveDefinite);
  ASSERT_TRUE(cholesky.factor_minor().has_value());
  EXPECT_GE(*cholesky.factor_minor(), 0);
  EXPECT_LT(*cholesky.factor_minor(), n);
  ASSERT_TRUE(cholesky.failed_column().has_value());
  EXPECT_LT(*cholesky.failed_column(), n);
  EXPECT_FALSE(cholesky.factorised());
  Eigen::VectorXd x(n);
  EXPECT_EQ(cholesky.solve(Eigen::VectorXd::Ones(n), x), SparseCholeskyStatus::kNotFactorised);

  // Fixing the value on the same pattern recovers.
  A.coeffRef(bad, bad) = 4.0;
  ASSERT_EQ(cholesky.factorise(A), SparseCholeskyStatus::kOk);
  EXPECT_FALSE(cholesky.failed_column().has_value());
  ASSERT_EQ(cholesky.solve(Eigen::VectorXd::Ones(n), x), SparseCholeskyStatus::kOk);
  EXPECT_LT((A * x - Eigen::VectorXd::Ones(n)).norm(), 1e-12);

  // A negative diagonal matrix entry that is isolated fails exactly at its column.
  SparseMatrix D(n, n);
  D.setIdentity();
  D.coeffRef(bad, bad) = -1.0;
  D.makeCompressed();
  SparseCholesky diagonal;
  EXPECT_EQ(diagonal.compute(D), SparseCholeskyStatus::kNotPositiveDefinite);
  EXPECT_EQ(diagonal.failed_column(), std::optional<Eigen::Index>(bad));
}

TEST(SparseCholesky, SimplicialAndSupernodalAgreeAndBothReportNotPositiveDefinite) {
  // The two numeric methods factor the same matrix; supernodal's dense kernels round differently,
  // so they agree to rounding, not bit for bit. Both stop at a non-positive pivot (simplicial only
  // because the factor is LLᵀ: an LDLᵀ one would accept it).
  const SparseMatrix A = box_laplacian(0.05);
  std::mt19937 gen(13);
  Eigen::MatrixXd B(A.rows(), 5);
  for (Eigen::Index j = 0; j < B.cols(); ++j) B.col(j) = testing::random_vector(A.rows(), 1.0, gen);
  Eigen::MatrixXd X[2];
  const SparseCholeskyMethod methods[2] = {SparseCholeskyMethod::kSimplicial,
                                           SparseCholeskyMethod::kSupernodal};
  for (int k = 0; k < 2; ++k) {
    SparseCholesky cholesky(SparseCholeskyOptions{SparseCholeskyOrdering::kMetis, methods[k]});
    ASSERT_EQ(cholesky.compute(A), SparseCholeskyStatus::kOk) << to_string(methods[k]);
    X[k].resize(A.rows(), B.cols());
    ASSERT_EQ(cholesky.solve_in_blocks(B, X[k], 2, 2), SparseCholeskyStatus::kOk);
    EXPECT_LT((A * X[k] - B).norm(), 1e-10 * B.norm()) << to_string(methods[k]);

    SparseMatrix indefinite = A;
    indefinite.coeffRef(7, 7) = -1.0;
    EXPECT_EQ(cholesky.factorise(indefinite), SparseCholeskyStatus::kNotPositiveDefinite)
        << to_string(methods[k]);
    EXPECT_TRUE(cholesky.failed_column().has_value());
  }
  EXPECT_GT(X[0].norm(), 0.0);
  EXPECT_LT(relative_difference(X[0], X[1]), 1e-12);

  // kAuto picks by the factor's size, the same on every machine.
  SparseCholesky automatic;
  ASSERT_EQ(automatic.analyse(A), SparseCholeskyStatus::kOk);
  EXPECT_EQ(automatic.method_used(), SparseCholeskyMethod::kSimplicial);
  SparseCholeskyOptions small_switch;
  small_switch.simplicial_max_factor_nonzeros = 10.0;
  SparseCholesky large(small_switch);
  ASSERT_EQ(large.compute(A), SparseCholeskyStatus::kOk);
  EXPECT_EQ(large.method_used(), SparseCholeskyMethod::kSupernodal);
}

TEST(SparseCholesky, OutOfOrderCallsAndBadShapesAreStatuses) {
  SparseCholesky cholesky;
  const SparseMatrix A = box_laplacian(0.1);
  Eigen::VectorXd x(A.rows());
  EXPECT_EQ(cholesky.factorise(A), SparseCholeskyStatus::kNotAnalysed);
  EXPECT_EQ(cholesky.solve(Eigen::VectorXd::Ones(A.rows()), x), SparseCholeskyStatus::kNotAnalysed);
  EXPECT_FALSE(cholesky.factor_nonzeros().has_value());
  SparseMatrix rectangular(4, 5);
  EXPECT_EQ(cholesky.analyse(rectangular), SparseCholeskyStatus::kInvalidInput);
  ASSERT_EQ(cholesky.analyse(A), SparseCholeskyStatus::kOk);
  EXPECT_EQ(cholesky.solve(Eigen::VectorXd::Ones(A.rows()), x),
            SparseCholeskyStatus::kNotFactorised);
}

}  // namespace
}  // namespace sinew::offline
