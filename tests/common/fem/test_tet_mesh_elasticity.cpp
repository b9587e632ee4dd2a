// Tests of common/fem/tet_mesh_elasticity: the whole-mesh elastic energy, its gradient and its
// sparse Hessian (through the sparse assembly) against finite differences.

#include "common/fem/tet_mesh_elasticity.hpp"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <cmath>
#include <string>
#include <vector>

#include "tests/support/finite_difference.hpp"
#include "tests/support/tet_mesh_fixtures.hpp"

namespace {

using sinew::common::HessianProjection;
using sinew::common::PatternStorage;
using sinew::common::StableNeoHookean;
using sinew::common::TetMeshElasticity;
using sinew::common::TetMeshStatus;
using sinew::testing::derivatives_match;

StableNeoHookean tissue() {
  return *StableNeoHookean::create({/*youngs_modulus=*/3e3, /*poisson_ratio=*/0.45});
}

struct NamedState {
  std::string name;
  Eigen::VectorXd x;
};

// Deformed states of a mesh: smooth affine + noise, strongly compressed (some tets inverted),
// and with one tet squashed to a small singular value.
std::vector<NamedState> deformed_states(const sinew::testing::TetMesh& mesh, std::mt19937& gen) {
  const Eigen::VectorXd X = sinew::common::to_dof_vector(mesh.rest_positions);
  const Eigen::Index n = X.size();
  std::vector<NamedState> states;
  Eigen::Matrix3d A = Eigen::Matrix3d::Identity() +
                      sinew::common::unvec(sinew::testing::random_vector(9, 0.2, gen));
  Eigen::VectorXd x(n);
  for (Eigen::Index v = 0; v < n / 3; ++v) x.segment<3>(3 * v) = A * X.segment<3>(3 * v);
  states.push_back({"affine + noise", x + sinew::testing::random_vector(n, 0.05, gen)});
  states.push_back({"large noise, inverted tets", X + sinew::testing::random_vector(n, 0.6, gen)});
  A = Eigen::Vector3d(1.1, 0.9, 0.05).asDiagonal();
  for (Eigen::Index v = 0; v < n / 3; ++v) x.segment<3>(3 * v) = A * X.segment<3>(3 * v);
  states.push_back({"flattened to 5%", x + sinew::testing::random_vector(n, 0.005, gen)});
  return states;
}

TEST(TetMeshElasticity, GradientAndHessianMatchFiniteDifferences) {
  auto& gen = sinew::testing::rng();
  const auto mesh = sinew::testing::make_box_mesh(2, 1, 1, 0.5);
  auto elasticity = TetMeshElasticity::create(mesh.rest_positions, mesh.tets, tissue());
  ASSERT_TRUE(elasticity);
  const auto energy = [&](const Eigen::VectorXd& x) { return elasticity->energy(x); };
  const auto gradient = [&](const Eigen::VectorXd& x) -> Eigen::VectorXd {
    Eigen::VectorXd g(x.size());
    elasticity->gradient(x, g);
    return g;
  };
  for (const auto& [name, x] : deformed_states(mesh, gen)) {
    SCOPED_TRACE(name);
    const Eigen::VectorXd g = gradient(x);
    EXPECT_TRUE(derivatives_match(g, sinew::testing::fd_gradient(energy, x, 1e-5), 1e-6));
    const Eigen::MatrixXd H = elasticity->hessian(x);
    EXPECT_TRUE(derivatives_match(H, sinew::testing::fd_jacobian(gradient, x, 1e-5), 1e-6));
  }
}

TEST(TetMeshElasticity, EnergyIsSumOfElementEnergies) {
  auto& gen = sinew::testing::rng();
  const auto mesh = sinew::testing::make_box_mesh(1, 2, 1);
  const auto material = tissue();
  const auto elasticity = TetMeshElasticity::create(mesh.rest_positions, mesh.tets, material);
  ASSERT_TRUE(elasticity);
  const Eigen::VectorXd x = deformed_states(mesh, gen).front().x;
  double sum = 0.0;
  for (Eigen::Index t = 0; t < mesh.tets.rows(); ++t) {
    sinew::common::Matrix3x4d X;
    for (int a = 0; a < 4; ++a) X.col(a) = mesh.rest_positions.row(mesh.tets(t, a)).transpose();
    sum += sinew::common::tet_elastic_energy(material, sinew::common::make_tet4_rest(X),
                                             elasticity->tet_positions(t, x));
  }
  EXPECT_NEAR(elasticity->energy(x), sum, 1e-12 * std::abs(sum));
  EXPECT_GT(sum, 0.0);
}

TEST(TetMeshElasticity, RigidMotionsAreFreeOfEnergyAndForce) {
  auto& gen = sinew::testing::rng();
  const auto mesh = sinew::testing::make_box_mesh(2, 1, 1);
  const auto material = tissue();
  const auto elasticity = TetMeshElasticity::create(mesh.rest_positions, mesh.tets, material);
  ASSERT_TRUE(elasticity);
  const Eigen::Matrix3d R = sinew::testing::rotation_about({1.0, 2.0, -0.5}, 3.0);
  const Eigen::Vector3d t(4.0, -1.0, 0.5);
  const Eigen::VectorXd X = sinew::common::to_dof_vector(mesh.rest_positions);
  Eigen::VectorXd x(X.size());
  for (Eigen::Index v = 0; v < X.size() / 3; ++v) x.segment<3>(3 * v) = R * X.segment<3>(3 * v) + t;
  const double force_scale = material.mu() * 1.0;  // stress times area, 1 m cubes
  EXPECT_NEAR(elasticity->energy(x), 0.0, 1e-10 * force_scale);
  Eigen::VectorXd g(x.size());
  elasticity->gradient(x, g);
  EXPECT_LT(g.norm(), 1e-10 * force_scale);
  // Not trivially zero elsewhere.
  const Eigen::VectorXd y = x + sinew::testing::random_vector(x.size(), 0.1, gen);
  elasticity->gradient(y, g);
  EXPECT_GT(g.norm(), 1e-3 * force_scale);
}

TEST(TetMeshElasticity, ProjectedHessianIsPositiveSemiDefinite) {
  auto& gen = sinew::testing::rng();
  const auto mesh = sinew::testing::make_box_mesh(2, 1, 1);
  const auto states = deformed_states(mesh, gen);
  for (const auto projection :
       {HessianProjection::kProjectDPdF, HessianProjection::kProjectElement}) {
    sinew::common::TetMeshElasticityOptions options;
    options.projection = projection;
    auto projected = TetMeshElasticity::create(mesh.rest_positions, mesh.tets, tissue(), options);
    auto exact = TetMeshElasticity::create(mesh.rest_positions, mesh.tets, tissue());
    ASSERT_TRUE(projected && exact);
    const Eigen::VectorXd& x = states[1].x;  // inverted tets: the exact Hessian is indefinite
    const Eigen::MatrixXd H_exact = exact->hessian(x);
    const Eigen::MatrixXd H = projected->hessian(x);
    const double scale = H_exact.norm();
    ASSERT_LT(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(H_exact).eigenvalues().minCoeff(),
              -1e-3 * scale);
    EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(H).eigenvalues().minCoeff(),
              -1e-10 * scale);
  }
}

TEST(TetMeshElasticity, HessianReusesPatternAndUpperStorageMatches) {
  auto& gen = sinew::testing::rng();
  const auto mesh = sinew::testing::make_box_mesh(2, 1, 1);
  const auto states = deformed_states(mesh, gen);
  auto full = TetMeshElasticity::create(mesh.rest_positions, mesh.tets, tissue());
  sinew::common::TetMeshElasticityOptions options;
  options.storage = PatternStorage::kUpper;
  auto upper = TetMeshElasticity::create(mesh.rest_positions, mesh.tets, tissue(), options);
  ASSERT_TRUE(full && upper);
  const auto& H0 = full->hessian(states[0].x);
  const double* values = H0.valuePtr();
  const Eigen::Index nnz = H0.nonZeros();
  const Eigen::MatrixXd first = H0;
  const auto& H1 = full->hessian(states[1].x);
  EXPECT_EQ(&H0, &H1);
  EXPECT_EQ(H1.valuePtr(), values);
  EXPECT_EQ(H1.nonZeros(), nnz);
  EXPECT_GT((Eigen::MatrixXd(H1) - first).norm(), 0.0);
  const Eigen::SparseMatrix<double> symmetric =
      upper->hessian(states[1].x).selfadjointView<Eigen::Upper>();
  const Eigen::MatrixXd from_upper = symmetric;
  EXPECT_LT((from_upper - Eigen::MatrixXd(H1)).norm(), 1e-12 * first.norm());
}

TEST(TetMeshElasticity, InvalidMeshesAreReportedWithTheTet) {
  auto mesh = sinew::testing::make_box_mesh(1, 1, 1);
  sinew::common::TetMeshCheck check;
  EXPECT_TRUE(TetMeshElasticity::create(mesh.rest_positions, mesh.tets, tissue(), {}, &check));
  EXPECT_TRUE(check.ok());

  auto inverted = mesh;
  std::swap(inverted.tets(2, 0), inverted.tets(2, 1));
  EXPECT_FALSE(
      TetMeshElasticity::create(inverted.rest_positions, inverted.tets, tissue(), {}, &check));
  EXPECT_EQ(check.status, TetMeshStatus::kInvertedTet);
  ASSERT_TRUE(check.tet);
  EXPECT_EQ(*check.tet, 2);
  EXPECT_NE(check.message().find("tet 2"), std::string::npos);

  auto degenerate = mesh;
  degenerate.tets(5, 3) = degenerate.tets(5, 2);
  EXPECT_EQ(sinew::common::check_tet_mesh(degenerate.rest_positions, degenerate.tets).status,
            TetMeshStatus::kDegenerateTet);

  auto out_of_range = mesh;
  out_of_range.tets(1, 1) = 8;
  check = sinew::common::check_tet_mesh(out_of_range.rest_positions, out_of_range.tets);
  EXPECT_EQ(check.status, TetMeshStatus::kIndexOutOfRange);
  EXPECT_EQ(check.tet, 1);

  sinew::common::TetMeshElasticityOptions bad_options;
  bad_options.degeneracy_tolerance = -1.0;
  ASSERT_TRUE(bad_options.validate());
  EXPECT_NE(bad_options.validate()->find("degeneracy_tolerance"), std::string::npos);
  EXPECT_FALSE(
      TetMeshElasticity::create(mesh.rest_positions, mesh.tets, tissue(), bad_options, &check));
  EXPECT_EQ(check.status, TetMeshStatus::kInvalidOptions);
}

}  // namespace
