// Tests of common/fem/mass: consistent and lumped tetrahedron mass, element and assembled.

#include "common/fem/mass.hpp"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>

#include "common/fem/tet4.hpp"
#include "tests/support/finite_difference.hpp"
#include "tests/support/tet_mesh_fixtures.hpp"

namespace {

using sinew::common::Matrix12d;
using sinew::common::Matrix3x4d;

Matrix3x4d random_tet(std::mt19937& gen) {
  Matrix3x4d X;
  do {
    X = Eigen::Map<const Matrix3x4d>(sinew::testing::random_vector(12, 1.0, gen).data());
  } while (std::abs(sinew::common::shape_quality(X)) < 0.1);
  return X;
}

constexpr double kDensity = 1070.0;  // kg/m³, soft tissue

TEST(Mass, ConsistentMassSumsToThreeTimesTetMass) {
  auto& gen = sinew::testing::rng();
  const Matrix3x4d X = random_tet(gen);
  const double V = std::abs(sinew::common::signed_volume(X));
  const Matrix12d M = sinew::common::consistent_mass_matrix(kDensity, V);
  // Every 3x3 block is a multiple of I, so the 144 entries sum to 3ρV (ρV per direction x, y, z).
  EXPECT_NEAR(M.sum(), 3.0 * kDensity * V, 1e-12 * kDensity * V);
  for (int d = 0; d < 3; ++d) {
    double direction_sum = 0.0;
    for (int a = 0; a < 4; ++a) {
      for (int b = 0; b < 4; ++b) direction_sum += M(3 * a + d, 3 * b + d);
    }
    EXPECT_NEAR(direction_sum, kDensity * V, 1e-12 * kDensity * V);
  }
  EXPECT_EQ(M, M.transpose());
  // Kinetic energy of a rigid translation: ½ vᵀ M v = ½ m |v|².
  const Eigen::Vector3d v(0.3, -1.0, 2.0);
  const sinew::common::Vector12d q = v.replicate<4, 1>();
  EXPECT_NEAR(0.5 * q.dot(M * q), 0.5 * kDensity * V * v.squaredNorm(), 1e-12 * kDensity * V);
  // The sign of the volume (vertex order) does not matter.
  EXPECT_EQ(sinew::common::consistent_mass_matrix(kDensity, -V), M);
}

TEST(Mass, ConsistentMassEqualsQuadratureOfShapeFunctionProducts) {
  // ∫ ρ NᵀN dΩ, N = [φ0 I, φ1 I, φ2 I, φ3 I], with the 4-point rule (exact for quadratics, and φ_a
  // φ_b is quadratic), evaluating φ at physical points through barycentric_coordinates.
  auto& gen = sinew::testing::rng();
  const Matrix3x4d X = random_tet(gen);
  const double V = std::abs(sinew::common::signed_volume(X));
  const double alpha = 0.5854101966249685;
  const double beta = 0.1381966011250105;
  Matrix12d quadrature = Matrix12d::Zero();
  for (int q = 0; q < 4; ++q) {
    Eigen::Vector4d lambda = Eigen::Vector4d::Constant(beta);
    lambda(q) = alpha;
    const Eigen::Vector3d point = X * lambda;
    const auto phi = sinew::common::barycentric_coordinates(X, point);
    ASSERT_TRUE(phi);
    Eigen::Matrix<double, 3, 12> N;
    for (int a = 0; a < 4; ++a) N.middleCols<3>(3 * a) = (*phi)(a)*Eigen::Matrix3d::Identity();
    quadrature += (V / 4.0) * kDensity * N.transpose() * N;
  }
  const Matrix12d M = sinew::common::consistent_mass_matrix(kDensity, V);
  EXPECT_LT((M - quadrature).norm(), 1e-12 * M.norm());
}

TEST(Mass, LumpedMassIsRowSumOfConsistentMass) {
  auto& gen = sinew::testing::rng();
  const double V = std::abs(sinew::common::signed_volume(random_tet(gen)));
  const Eigen::Vector4d lumped = sinew::common::lumped_vertex_masses(kDensity, V);
  EXPECT_NEAR(lumped.sum(), kDensity * V, 1e-12 * kDensity * V);
  const Matrix12d M = sinew::common::consistent_mass_matrix(kDensity, V);
  for (int a = 0; a < 4; ++a) EXPECT_NEAR(lumped(a), M.row(3 * a).sum(), 1e-12 * kDensity * V);
}

TEST(Mass, AssembledMassOfBoxMesh) {
  const auto mesh = sinew::testing::make_box_mesh(2, 1, 1, 0.5);
  const double box_volume = 2 * 0.5 * 0.5 * 0.5;
  const auto M = sinew::common::assemble_consistent_mass(mesh.rest_positions, mesh.tets, kDensity);
  ASSERT_TRUE(M);
  const Eigen::MatrixXd dense = M->toDense();
  EXPECT_NEAR(dense.sum(), 3.0 * kDensity * box_volume, 1e-10);

  // Equals a dense assembly of the element matrices.
  Eigen::MatrixXd expected = Eigen::MatrixXd::Zero(dense.rows(), dense.cols());
  for (Eigen::Index t = 0; t < mesh.tets.rows(); ++t) {
    Matrix3x4d X;
    for (int a = 0; a < 4; ++a) X.col(a) = mesh.rest_positions.row(mesh.tets(t, a)).transpose();
    const Matrix12d Me =
        sinew::common::consistent_mass_matrix(kDensity, sinew::common::signed_volume(X));
    for (int a = 0; a < 4; ++a) {
      for (int b = 0; b < 4; ++b) {
        expected.block<3, 3>(3 * mesh.tets(t, a), 3 * mesh.tets(t, b)) +=
            Me.block<3, 3>(3 * a, 3 * b);
      }
    }
  }
  EXPECT_LT((dense - expected).norm(), 1e-14 * expected.norm());

  const auto upper = sinew::common::assemble_consistent_mass(
      mesh.rest_positions, mesh.tets, kDensity, sinew::common::PatternStorage::kUpper);
  ASSERT_TRUE(upper);
  const Eigen::SparseMatrix<double> symmetric = upper->selfadjointView<Eigen::Upper>();
  const Eigen::MatrixXd from_upper = symmetric;
  EXPECT_LT((from_upper - expected).norm(), 1e-14 * expected.norm());

  const auto lumped = sinew::common::assemble_lumped_mass(mesh.rest_positions, mesh.tets, kDensity);
  ASSERT_TRUE(lumped);
  EXPECT_EQ(lumped->size(), mesh.rest_positions.rows());
  EXPECT_NEAR(lumped->sum(), kDensity * box_volume, 1e-10);
  // Row-sum lumping holds globally too: per vertex, the x-row sum of the consistent matrix.
  for (Eigen::Index v = 0; v < lumped->size(); ++v) {
    EXPECT_NEAR((*lumped)(v), dense.row(3 * v).sum(), 1e-12);
  }
}

TEST(Mass, OutOfRangeIndexIsReported) {
  auto mesh = sinew::testing::make_box_mesh(1, 1, 1);
  mesh.tets(3, 2) = static_cast<int>(mesh.rest_positions.rows());
  EXPECT_FALSE(sinew::common::assemble_consistent_mass(mesh.rest_positions, mesh.tets, kDensity));
  EXPECT_FALSE(sinew::common::assemble_lumped_mass(mesh.rest_positions, mesh.tets, kDensity));
}

}  // namespace
