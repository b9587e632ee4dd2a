// Tests of offline/singular_solver (seed 003 §3.5, Singular Lemma (ii)): for the tangent stiffness
// of a free object at a static equilibrium (six-dimensional rigid nullspace), the pinned-Cholesky
// solve equals the dense solve of the bordered system (eq. 15) and the pseudo-inverse solution,
// is orthogonal to the nullspace and solves K y = b in every row; the pins make K positive
// definite, which the unpinned K is not.

#include "offline/linalg/singular_solver.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>

#include "offline/equilibrium/equilibrium.hpp"
#include "offline/plastic/plastic_elastic_energy.hpp"
#include "offline/plastic/plastic_strain.hpp"
#include "offline/rigid/rigid_motion.hpp"
#include "tests/support/offline_fixtures.hpp"
#include "tests/support/tet_mesh_fixtures.hpp"

namespace sinew::offline {
namespace {

TEST(RigidNullspaceSolver, MatchesTheBorderedSystemAndThePseudoInverse) {
  const testing::TetMesh mesh = testing::make_box_mesh(2, 2, 1, 0.05);
  auto energy =
      PlasticElasticEnergy::create(mesh.rest_positions, mesh.tets, testing::soft_tissue());
  ASSERT_TRUE(energy.has_value());
  // A non-uniform plastic state and its free equilibrium (so K has exactly the rigid nullspace).
  Eigen::VectorXd s = identity_plastic_strains(mesh.tets.rows());
  for (Eigen::Index t = 0; t < mesh.tets.rows(); ++t) {
    Eigen::Matrix3d Fp = Eigen::Matrix3d::Identity();
    Fp(0, 0) = 1.0 + 0.05 * static_cast<double>(t % 5);
    Fp(1, 2) = Fp(2, 1) = 0.03 * static_cast<double>(t % 3);
    s.segment<6>(6 * t) = plastic_strain_vector(Fp);
  }
  auto none = PointConstraints::create(mesh.rest_positions.rows(), mesh.tets, {});
  auto equilibrium = EquilibriumSolver::create(*energy, *none);
  ASSERT_TRUE(equilibrium.has_value());
  Eigen::VectorXd x = energy->rest_dofs();
  ASSERT_TRUE(equilibrium->solve(s, x).converged());
  PlasticEnergyRequest request;
  request.stiffness = true;
  ASSERT_TRUE(energy->evaluate(s, x, request).valid());
  const Eigen::SparseMatrix<double> K = energy->stiffness();
  const Eigen::MatrixXd dense = Eigen::MatrixXd(K);
  const Eigen::Index n = dense.rows();

  // K itself is singular: Cholesky fails on it.
  SparseCholesky plain;
  EXPECT_NE(plain.compute(K), SparseCholeskyStatus::kOk);

  RigidNullspaceSolver solver;
  ASSERT_EQ(solver.factorise(K, x), SparseCholeskyStatus::kOk);
  const auto& psi = solver.nullspace();

  // Right-hand sides in the range of K: K times random vectors.
  std::mt19937 rng(1);
  std::normal_distribution<double> normal;
  Eigen::MatrixXd random(n, 3);
  for (Eigen::Index i = 0; i < random.size(); ++i) random.data()[i] = normal(rng);
  const Eigen::MatrixXd b = dense * random;
  Eigen::MatrixXd y;
  ASSERT_EQ(solver.solve(b, y), SparseCholeskyStatus::kOk);

  // Eq. 15, dense: [K Ψ; Ψᵀ 0] [y; λ] = [b; 0].
  Eigen::MatrixXd bordered = Eigen::MatrixXd::Zero(n + 6, n + 6);
  bordered.topLeftCorner(n, n) = dense;
  bordered.topRightCorner(n, 6) = psi;
  bordered.bottomLeftCorner(6, n) = psi.transpose();
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(n + 6, 3);
  rhs.topRows(n) = b;
  const Eigen::MatrixXd eq15 = bordered.fullPivLu().solve(rhs).topRows(n);
  // The pseudo-inverse solution.
  Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod(dense.rows(), dense.cols());
  cod.setThreshold(1e-10);
  cod.compute(dense);
  EXPECT_EQ(cod.rank(), n - 6);  // exactly the six rigid motions are missing
  const Eigen::MatrixXd pinv = cod.pseudoInverse() * b;

  const double scale = y.norm();
  EXPECT_GT(scale, 0.0);
  EXPECT_LT((y - eq15).norm(), 1e-7 * scale);
  EXPECT_LT((y - pinv).norm(), 1e-7 * scale);
  EXPECT_LT((psi.transpose() * y).norm(), 1e-10 * scale);
  EXPECT_LT((dense * y - b).norm(), 1e-7 * b.norm());
}

TEST(RigidNullspaceSolver, RefusesCollinearPositionsAndWrongSizes) {
  RigidNullspaceSolver solver;
  Eigen::VectorXd line(9);
  line << 0, 0, 0, 1, 1, 1, 2, 2, 2;
  Eigen::SparseMatrix<double> I(9, 9);
  I.setIdentity();
  EXPECT_EQ(solver.factorise(I, line), SparseCholeskyStatus::kInvalidInput);
  EXPECT_EQ(solver.factorise(I, Eigen::VectorXd::Zero(6)), SparseCholeskyStatus::kInvalidInput);
}

}  // namespace
}  // namespace sinew::offline
