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
#include <vector>

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

// Held tets (set_constraint_rows_transposed_holding): y is 0 on them and solves the free tets'
// rows of H y = h, against a dense solve of H restricted to the free entries; the limit of the
// penalty rows big·eᵢᵀ per held entry (what gauss_newton adds below held_penalty_max_bytes); and
// the kept rows and capacitance do not grow with the held tets, where the penalty rows' do.
TEST(WoodburySolver, HeldTetsAreEliminatedWithoutExtraRows) {
  const System system = make_system(4, 3, 2);
  const Eigen::Index n = 6 * system.m;
  const Eigen::MatrixXd Z = 30.0 * random_matrix(15, n, 7);
  const Eigen::VectorXd h = random_matrix(n, 1, 8);
  std::vector<Eigen::Index> held;
  for (Eigen::Index t = 0; t < system.m; t += 3) held.push_back(t);
  ASSERT_GT(held.size(), 20u);
  auto solver = WoodburySolver::create(system.laplacian.adjacency, system.m);
  ASSERT_TRUE(solver.has_value());
  ASSERT_EQ(solver->set_constraint_rows_transposed_holding(Z.transpose(), held, 0.1),
            WoodburyStatus::kOk);
  EXPECT_EQ(solver->held_tets(), static_cast<Eigen::Index>(held.size()));
  EXPECT_EQ(solver->constraint_rows(), 15);
  EXPECT_EQ(solver->capacitance_size(), 15 + 6);
  Eigen::VectorXd y(n);
  ASSERT_EQ(solver->solve(h, y), WoodburyStatus::kOk);

  // Dense reference on the free entries.
  std::vector<char> is_held(static_cast<std::size_t>(system.m), 0);
  for (Eigen::Index t : held) is_held[static_cast<std::size_t>(t)] = 1;
  std::vector<Eigen::Index> free;
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!is_held[static_cast<std::size_t>(i / 6)]) free.push_back(i);
  }
  const double delta = solver->nullspace_damping();
  EXPECT_NEAR(delta, 0.1 * (Z * system.Psi).squaredNorm() / 6.0 + 1e-12, 1e-9 * delta);
  const Eigen::MatrixXd H =
      system.L * system.L + Z.transpose() * Z + delta * system.Psi * system.Psi.transpose();
  const Eigen::Index f = static_cast<Eigen::Index>(free.size());
  Eigen::MatrixXd H_free(f, f);
  Eigen::VectorXd h_free(f);
  for (Eigen::Index i = 0; i < f; ++i) {
    h_free[i] = h[free[static_cast<std::size_t>(i)]];
    for (Eigen::Index j = 0; j < f; ++j)
      H_free(i, j) = H(free[static_cast<std::size_t>(i)], free[static_cast<std::size_t>(j)]);
  }
  const Eigen::VectorXd dense = H_free.ldlt().solve(h_free);
  Eigen::VectorXd y_free(f);
  for (Eigen::Index i = 0; i < f; ++i) y_free[i] = y[free[static_cast<std::size_t>(i)]];
  EXPECT_LT((y_free - dense).norm() / dense.norm(), 1e-8);
  for (Eigen::Index t : held) EXPECT_EQ(y.segment<6>(6 * t).norm(), 0.0) << "tet " << t;

  // The penalty rows (gauss_newton's: 1e3 times the largest row norm of Zᵀ) approach it, with
  // six more rows per held tet in Zᵀ and in the capacitance.
  const double big = 1e3 * Z.transpose().rowwise().norm().maxCoeff();
  const Eigen::Index extra = 6 * static_cast<Eigen::Index>(held.size());
  Eigen::MatrixXd Zt_penalty = Eigen::MatrixXd::Zero(n, 15 + extra);
  Zt_penalty.leftCols(15) = Z.transpose();
  for (std::size_t k = 0; k < held.size(); ++k) {
    for (int i = 0; i < 6; ++i)
      Zt_penalty(6 * held[k] + i, 15 + 6 * static_cast<Eigen::Index>(k) + i) = big;
  }
  auto penalty = WoodburySolver::create(system.laplacian.adjacency, system.m);
  ASSERT_TRUE(penalty.has_value());
  // Told the penalty, the held solve takes the δ those rows give (they enter ‖ZΨ‖²).
  ASSERT_EQ(solver->set_constraint_rows_transposed_holding(Z.transpose(), held, 0.1, 0.0, big),
            WoodburyStatus::kOk);
  ASSERT_EQ(solver->solve(h, y), WoodburyStatus::kOk);
  ASSERT_EQ(penalty->set_constraint_rows_transposed(Zt_penalty, 0.1), WoodburyStatus::kOk);
  EXPECT_NEAR(solver->nullspace_damping(), penalty->nullspace_damping(),
              1e-9 * penalty->nullspace_damping());
  EXPECT_GT(penalty->nullspace_damping(), 1e3 * delta);
  EXPECT_EQ(penalty->constraint_rows(), 15 + extra);
  EXPECT_EQ(penalty->capacitance_size(), 15 + extra + 6);
  Eigen::VectorXd y_penalty(n);
  ASSERT_EQ(penalty->solve(h, y_penalty), WoodburyStatus::kOk);
  EXPECT_LT((y_penalty - y).norm() / y.norm(), 1e-4);

  // Back to the plain solve: nothing held.
  ASSERT_EQ(solver->set_constraint_rows_transposed(Z.transpose()), WoodburyStatus::kOk);
  EXPECT_EQ(solver->held_tets(), 0);
  ASSERT_EQ(solver->solve(h, y), WoodburyStatus::kOk);
  const Eigen::MatrixXd H0 = system.L * system.L + Z.transpose() * Z;
  EXPECT_LT((H0 * y - h).norm() / h.norm(), 1e-8);

  // Every tet held, or an index out of range: invalid.
  std::vector<Eigen::Index> all(static_cast<std::size_t>(system.m));
  for (Eigen::Index t = 0; t < system.m; ++t) all[static_cast<std::size_t>(t)] = t;
  EXPECT_EQ(solver->set_constraint_rows_transposed_holding(Z.transpose(), all),
            WoodburyStatus::kInvalidInput);
  EXPECT_EQ(solver->set_constraint_rows_transposed_holding(Z.transpose(), {system.m}),
            WoodburyStatus::kInvalidInput);
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
