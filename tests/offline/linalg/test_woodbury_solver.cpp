// Tests of offline/woodbury_solver: the Gauss–Newton system H y = h, H = L² + ZᵀZ, of seed 003
// (eqs. 11–14). (a) B⁻¹ = (L²)⁺ − ΨΨᵀ really inverts B = L² − ΨΨᵀ (formed densely on a small
// mesh); (b) the Woodbury solve equals a dense solve of H; (c) conjugate gradients on H agree with
// it to 1e-6 relative (the paper's Table 1 comparison); (d) bad inputs are statuses.

#include "offline/linalg/woodbury_solver.hpp"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <cstdio>
#include <random>
#include <string>

#include "offline/plastic/plastic_strain_laplacian.hpp"
#include "tests/support/tet_mesh_fixtures.hpp"

namespace sinew::offline {
namespace {

Eigen::MatrixXd random_matrix(Eigen::Index rows, Eigen::Index cols, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXd A(rows, cols);
  for (Eigen::Index j = 0; j < cols; ++j) {
    for (Eigen::Index i = 0; i < rows; ++i) A(i, j) = normal(rng);
  }
  return A;
}

struct System {
  PlasticStrainLaplacian laplacian;
  Eigen::Index m = 0;
  Eigen::MatrixXd L;  // dense 6m x 6m
  Eigen::MatrixXd Psi;
};

System make_system(int nx, int ny, int nz) {
  System system;
  const testing::TetMesh mesh = testing::make_box_mesh(nx, ny, nz, 0.1);
  system.laplacian = make_plastic_strain_laplacian(mesh.tets);
  system.m = mesh.tets.rows();
  system.L = Eigen::MatrixXd(system.laplacian.matrix);
  system.Psi = plastic_strain_laplacian_nullspace(system.m);
  return system;
}

TEST(WoodburySolver, BaseInverseInvertsLSquaredMinusNullspace) {
  const System system = make_system(2, 2, 1);
  auto solver = WoodburySolver::create(system.laplacian.adjacency, system.m);
  ASSERT_TRUE(solver.has_value());
  const Eigen::MatrixXd B = system.L * system.L - system.Psi * system.Psi.transpose();
  const Eigen::MatrixXd V = random_matrix(6 * system.m, 5, 1);
  Eigen::MatrixXd BinvV(V.rows(), V.cols());
  ASSERT_EQ(solver->apply_base_inverse(V, BinvV), WoodburyStatus::kOk);
  const double error = (B * BinvV - V).norm() / V.norm();
  EXPECT_LT(error, 1e-10);
  // The nullspace block alone: B⁻¹ψ = −ψ.
  Eigen::MatrixXd Binv_psi(V.rows(), 6);
  ASSERT_EQ(solver->apply_base_inverse(system.Psi, Binv_psi), WoodburyStatus::kOk);
  EXPECT_LT((Binv_psi + system.Psi).norm(), 1e-10);
}

TEST(WoodburySolver, MatchesADenseSolveAndConjugateGradients) {
  const System system = make_system(3, 2, 2);
  WoodburySolverOptions options;
  options.block_columns = 4;  // several blocks
  auto solver = WoodburySolver::create(system.laplacian.adjacency, system.m, options);
  ASSERT_TRUE(solver.has_value());
  // 5 markers (15 rows), scaled like constraint rows that dominate the Laplacian.
  const Eigen::MatrixXd Z = 30.0 * random_matrix(15, 6 * system.m, 2);
  const Eigen::VectorXd h = random_matrix(6 * system.m, 1, 3);
  ASSERT_EQ(solver->set_constraint_rows_transposed(Z.transpose()), WoodburyStatus::kOk);
  Eigen::VectorXd y(h.size());
  ASSERT_EQ(solver->solve(h, y), WoodburyStatus::kOk);

  const Eigen::MatrixXd H = system.L * system.L + Z.transpose() * Z;
  const Eigen::VectorXd dense = H.ldlt().solve(h);
  EXPECT_LT((y - dense).norm() / dense.norm(), 1e-8);
  EXPECT_LT((H * y - h).norm() / h.norm(), 1e-8);

  // With the nullspace damping δΨΨᵀ, δ = 0.5·‖ZΨ‖²/6 + 1e-12.
  ASSERT_EQ(solver->set_constraint_rows_transposed(Z.transpose(), 0.5), WoodburyStatus::kOk);
  const double delta = 0.5 * (Z * system.Psi).squaredNorm() / 6.0 + 1e-12;
  EXPECT_NEAR(solver->nullspace_damping(), delta, 1e-9 * delta);
  Eigen::VectorXd damped(h.size());
  ASSERT_EQ(solver->solve(h, damped), WoodburyStatus::kOk);
  const Eigen::MatrixXd H_damped = H + delta * system.Psi * system.Psi.transpose();
  EXPECT_LT((H_damped * damped - h).norm() / h.norm(), 1e-8);
  EXPECT_GT((damped - y).norm(), 1e-6 * y.norm());

  Eigen::VectorXd cg(h.size());
  ConjugateGradientOptions cg_options;
  cg_options.relative_tolerance = 1e-10;
  const ConjugateGradientSummary summary =
      conjugate_gradient_solve(system.laplacian.matrix, Z.transpose(), h, cg, cg_options);
  EXPECT_LT(summary.relative_residual, 1e-8);
  EXPECT_GT(summary.iterations, 10);
  EXPECT_LT((cg - y).norm() / y.norm(), 1e-6);
}

// Iterative refinement (refinement_steps, default 1) against the plain eq. 14 solve on a system
// whose constraint rows dominate the Laplacian by 10⁶ (the capacitance matrix then loses digits):
// the refined residual is far smaller, including the damping δΨΨᵀ that H carries.
TEST(WoodburySolver, RefinementLowersTheResidualOfStiffConstraints) {
  const System system = make_system(4, 3, 3);
  // Nearly dependent rows (markers almost on top of each other): an ill-conditioned capacitance.
  const Eigen::MatrixXd base = random_matrix(3, 6 * system.m, 4);
  Eigen::MatrixXd Z(30, 6 * system.m);
  for (int k = 0; k < 10; ++k) Z.middleRows(3 * k, 3) = 1e3 * base;
  Z += 1e-3 * random_matrix(30, 6 * system.m, 6);
  const Eigen::VectorXd h = random_matrix(6 * system.m, 1, 5);
  double residual[2] = {0.0, 0.0};
  for (int steps : {0, 1}) {
    WoodburySolverOptions options;
    options.refinement_steps = steps;
    auto solver = WoodburySolver::create(system.laplacian.adjacency, system.m, options);
    ASSERT_TRUE(solver.has_value());
    ASSERT_EQ(solver->set_constraint_rows_transposed(Z.transpose(), 0.1), WoodburyStatus::kOk);
    Eigen::VectorXd y(h.size());
    ASSERT_EQ(solver->solve(h, y), WoodburyStatus::kOk);
    const Eigen::MatrixXd H = system.L * system.L + Z.transpose() * Z +
                              solver->nullspace_damping() * system.Psi * system.Psi.transpose();
    // Normwise backward error: what a backward-stable solve reaches is ~1e-16.
    residual[steps] = (H * y - h).norm() / (H.norm() * y.norm() + h.norm());
  }
  std::printf("backward error: plain %.3g, one refinement step %.3g\n", residual[0], residual[1]);
  EXPECT_LT(residual[1], 0.1 * residual[0]);
  EXPECT_LT(residual[1], 1e-15);
  WoodburySolverOptions bad;
  bad.refinement_steps = -1;
  EXPECT_TRUE(bad.validate().has_value());
}

TEST(WoodburySolver, ThreadsAndBlockSizesGiveTheSameStep) {
  // The Laplacian solves are split in column blocks over threads; neither the split nor the
  // huge-page advice may change the answer beyond rounding.
  const System system = make_system(3, 3, 2);
  const Eigen::MatrixXd Z = 30.0 * random_matrix(21, 6 * system.m, 5);
  const Eigen::VectorXd h = random_matrix(6 * system.m, 1, 6);
  auto step = [&](int threads, int block, bool huge_pages) {
    WoodburySolverOptions options;
    options.threads = threads;
    options.block_columns = block;
    options.huge_pages = huge_pages;
    auto solver = WoodburySolver::create(system.laplacian.adjacency, system.m, options);
    EXPECT_TRUE(solver.has_value());
    EXPECT_EQ(solver->set_constraint_rows_transposed(Z.transpose(), 0.5), WoodburyStatus::kOk);
    Eigen::VectorXd y(h.size());
    EXPECT_EQ(solver->solve(h, y), WoodburyStatus::kOk);
    return y;
  };
  const Eigen::VectorXd reference = step(1, 64, false);
  const double delta = 0.5 * (Z * system.Psi).squaredNorm() / 6.0 + 1e-12;
  const Eigen::MatrixXd H =
      system.L * system.L + Z.transpose() * Z + delta * system.Psi * system.Psi.transpose();
  EXPECT_LT((H * reference - h).norm() / h.norm(), 1e-8);
  for (const auto& [threads, block] : {std::pair{2, 1}, std::pair{3, 4}, std::pair{2, 16}}) {
    const Eigen::VectorXd y = step(threads, block, true);
    EXPECT_LT((y - reference).norm() / reference.norm(), 1e-12)
        << threads << " threads, blocks of " << block;
  }
}

TEST(WoodburySolver, BadInputsAreStatuses) {
  const System system = make_system(2, 1, 1);
  std::string error;
  WoodburySolverOptions bad;
  bad.block_columns = 0;
  EXPECT_FALSE(WoodburySolver::create(system.laplacian.adjacency, system.m, bad, &error));
  EXPECT_NE(error.find("block_columns"), std::string::npos) << error;
  bad.block_columns = 1;
  bad.threads = -1;
  EXPECT_FALSE(WoodburySolver::create(system.laplacian.adjacency, system.m, bad, &error));
  EXPECT_NE(error.find("threads = -1"), std::string::npos) << error;
  // Two disconnected boxes: L has 12 nullspace vectors, the method needs exactly 6.
  testing::TetMesh two = testing::make_box_mesh(1, 1, 1);
  const testing::TetMesh one = two;
  two.tets.conservativeResize(2 * one.tets.rows(), 4);
  two.tets.bottomRows(one.tets.rows()) = one.tets.array() + 8;
  const PlasticStrainLaplacian disconnected = make_plastic_strain_laplacian(two.tets);
  EXPECT_FALSE(WoodburySolver::create(disconnected.adjacency, two.tets.rows(), {}, &error));
  EXPECT_NE(error.find("components"), std::string::npos) << error;

  auto solver = WoodburySolver::create(system.laplacian.adjacency, system.m);
  ASSERT_TRUE(solver.has_value());
  Eigen::VectorXd y(6 * system.m);
  EXPECT_EQ(solver->solve(Eigen::VectorXd::Ones(6 * system.m), y), WoodburyStatus::kNotFactorised);
  EXPECT_EQ(solver->set_constraint_rows_transposed(Eigen::MatrixXd::Ones(5, 3)),
            WoodburyStatus::kInvalidInput);
  Eigen::MatrixXd nan_rows = Eigen::MatrixXd::Ones(6 * system.m, 3);
  nan_rows(2, 1) = std::nan("");
  EXPECT_EQ(solver->set_constraint_rows_transposed(nan_rows), WoodburyStatus::kInvalidInput);
}

}  // namespace
}  // namespace sinew::offline
