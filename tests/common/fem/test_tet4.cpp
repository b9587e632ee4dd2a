// Tests of common/fem/tet4: rest data, deformation gradient, dF/dx, barycentric coordinates.

#include "common/fem/tet4.hpp"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/LU>
#include <cmath>
#include <limits>

#include "tests/support/finite_difference.hpp"

namespace {

using sinew::common::Matrix3x4d;
using sinew::common::Tet4Status;
using sinew::common::vec;
using sinew::testing::derivatives_match;

Matrix3x4d reference_tet() {
  Matrix3x4d X = Matrix3x4d::Zero();
  X.rightCols<3>() = Eigen::Matrix3d::Identity();
  return X;
}

// A random right-handed tetrahedron of size ~1.
Matrix3x4d random_tet(std::mt19937& gen) {
  Matrix3x4d X;
  do {
    X = Eigen::Map<const Matrix3x4d>(sinew::testing::random_vector(12, 1.0, gen).data());
  } while (std::abs(sinew::common::shape_quality(X)) < 0.1);
  if (sinew::common::signed_volume(X) < 0) X.col(2).swap(X.col(3));
  return X;
}

// Nearly flat: the apex is 1e-3 above the base plane.
Matrix3x4d nearly_flat_tet() {
  Matrix3x4d X;
  X << 0.0, 1.0, 0.2, 0.4,  //
      0.0, 0.1, 1.0, 0.4,   //
      0.0, 0.0, 0.0, 1e-3;
  return X;
}

TEST(Tet4, ReferenceTetrahedron) {
  const auto rest = sinew::common::make_tet4_rest(reference_tet());
  ASSERT_EQ(rest.status, Tet4Status::kValid);
  EXPECT_EQ(rest.Dm, Eigen::Matrix3d::Identity());
  EXPECT_EQ(rest.Dm_inv, Eigen::Matrix3d::Identity());
  EXPECT_DOUBLE_EQ(rest.volume, 1.0 / 6.0);
  sinew::common::Matrix4x3d expected;
  expected << -1, -1, -1, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  EXPECT_EQ(rest.shape_gradients, expected);
}

TEST(Tet4, VolumeIsSignedAndRigidInvariant) {
  auto& gen = sinew::testing::rng();
  const Matrix3x4d X = random_tet(gen);
  const auto rest = sinew::common::make_tet4_rest(X);
  ASSERT_EQ(rest.status, Tet4Status::kValid);
  // V = (X1 − X0)·((X2 − X0) × (X3 − X0)) / 6, independently of the determinant.
  const Eigen::Vector3d e1 = X.col(1) - X.col(0), e2 = X.col(2) - X.col(0),
                        e3 = X.col(3) - X.col(0);
  EXPECT_NEAR(rest.volume, e1.dot(e2.cross(e3)) / 6.0, 1e-15);
  const Eigen::Matrix3d R = sinew::testing::random_rotation(gen);
  const Matrix3x4d moved = (R * X).colwise() + Eigen::Vector3d(3.0, -2.0, 1.0);
  EXPECT_NEAR(sinew::common::signed_volume(moved), rest.volume, 1e-14);

  Matrix3x4d swapped = X;
  swapped.col(1).swap(swapped.col(2));
  const auto inverted = sinew::common::make_tet4_rest(swapped);
  EXPECT_EQ(inverted.status, Tet4Status::kInverted);
  EXPECT_NEAR(inverted.volume, -rest.volume, 1e-15);
}

TEST(Tet4, DegenerateAndNonFiniteRestShapesAreReported) {
  Matrix3x4d coplanar = nearly_flat_tet();
  coplanar(2, 3) = 0.0;
  EXPECT_EQ(sinew::common::make_tet4_rest(coplanar).status, Tet4Status::kDegenerate);
  Matrix3x4d coincident = reference_tet();
  coincident.col(3) = coincident.col(2);
  EXPECT_EQ(sinew::common::make_tet4_rest(coincident).status, Tet4Status::kDegenerate);
  EXPECT_EQ(sinew::common::make_tet4_rest(Matrix3x4d::Zero()).status, Tet4Status::kDegenerate);
  Matrix3x4d nan_tet = reference_tet();
  nan_tet(0, 2) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(sinew::common::make_tet4_rest(nan_tet).status, Tet4Status::kNonFinite);
  // Nearly flat is still a valid element.
  EXPECT_EQ(sinew::common::make_tet4_rest(nearly_flat_tet()).status, Tet4Status::kValid);
  EXPECT_FALSE(sinew::common::barycentric_coordinates(coplanar, Eigen::Vector3d::Zero()));
}

TEST(Tet4, ShapeGradientsReproduceLinearFields) {
  auto& gen = sinew::testing::rng();
  for (const Matrix3x4d& X : {random_tet(gen), nearly_flat_tet()}) {
    const auto rest = sinew::common::make_tet4_rest(X);
    ASSERT_EQ(rest.status, Tet4Status::kValid);
    // Σ_a ∇φ_a = 0 (partition of unity) and Σ_a X_a ∇φ_aᵀ = I (linear precision).
    EXPECT_LT(rest.shape_gradients.colwise().sum().norm(), 1e-12 * rest.Dm_inv.norm());
    EXPECT_LT((X * rest.shape_gradients - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  }
}

TEST(Tet4, DeformationGradientOfRigidAndAffineMotions) {
  auto& gen = sinew::testing::rng();
  for (const Matrix3x4d& X : {random_tet(gen), nearly_flat_tet()}) {
    const auto rest = sinew::common::make_tet4_rest(X);
    const Eigen::Vector3d t(0.3, -1.2, 2.5);
    const Matrix3x4d translated = X.colwise() + t;
    EXPECT_LT((sinew::common::deformation_gradient(rest, translated) - Eigen::Matrix3d::Identity())
                  .norm(),
              1e-10);
    const Eigen::Matrix3d R = sinew::testing::random_rotation(gen);
    const Matrix3x4d rotated = (R * X).colwise() + t;
    EXPECT_LT((sinew::common::deformation_gradient(rest, rotated) - R).norm(), 1e-10);
    const Eigen::Matrix3d A = sinew::common::unvec(sinew::testing::random_vector(9, 1.0, gen));
    const Matrix3x4d affine = (A * X).colwise() + t;
    EXPECT_LT((sinew::common::deformation_gradient(rest, affine) - A).norm(), 1e-10 * A.norm());
  }
}

TEST(Tet4, DFdxTimesDofsIsVecF) {
  auto& gen = sinew::testing::rng();
  for (const Matrix3x4d& X : {random_tet(gen), nearly_flat_tet()}) {
    const auto rest = sinew::common::make_tet4_rest(X);
    const Matrix3x4d x =
        X + Eigen::Map<const Matrix3x4d>(sinew::testing::random_vector(12, 0.3, gen).data());
    const Eigen::Matrix3d F = sinew::common::deformation_gradient(rest, x);
    EXPECT_LT((rest.dFdx * sinew::common::to_element_dofs(x) - vec(F)).norm(), 1e-12 * F.norm());
  }
}

TEST(Tet4, DFdxMatchesFiniteDifferencesAndSeedLayout) {
  auto& gen = sinew::testing::rng();
  for (const Matrix3x4d& X : {random_tet(gen), nearly_flat_tet()}) {
    const auto rest = sinew::common::make_tet4_rest(X);
    const auto vec_F = [&rest](const Eigen::VectorXd& x) -> Eigen::VectorXd {
      return vec(sinew::common::deformation_gradient(rest, Eigen::Map<const Matrix3x4d>(x.data())));
    };
    const Eigen::VectorXd x0 = sinew::common::to_element_dofs(X);
    EXPECT_TRUE(derivatives_match(rest.dFdx, sinew::testing::fd_jacobian(vec_F, x0, 1e-4), 1e-9));
    // Seed 002's B stacks F row by row: B(3i + j, 3a + i) = D(a, j) with D = [−1ᵀT⁻¹; T⁻¹]; our
    // column-major dF/dx has row i + 3j where B has row 3i + j.
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) {
        Eigen::Matrix<double, 1, 12> seed_row = Eigen::Matrix<double, 1, 12>::Zero();
        for (int a = 0; a < 4; ++a) seed_row(3 * a + i) = rest.shape_gradients(a, j);
        EXPECT_EQ(rest.dFdx.row(i + 3 * j), seed_row);
      }
    }
  }
}

TEST(Tet4, BarycentricCoordinates) {
  auto& gen = sinew::testing::rng();
  const Matrix3x4d X = random_tet(gen);
  for (int a = 0; a < 4; ++a) {
    const auto phi = sinew::common::barycentric_coordinates(X, X.col(a));
    ASSERT_TRUE(phi);
    EXPECT_LT((*phi - Eigen::Vector4d::Unit(a)).norm(), 1e-12);
  }
  // A point with known weights is recovered; the weights sum to one.
  Eigen::Vector4d w = sinew::testing::random_vector(4, 1.0, gen).cwiseAbs();
  w /= w.sum();
  const auto phi = sinew::common::barycentric_coordinates(X, X * w);
  ASSERT_TRUE(phi);
  EXPECT_LT((*phi - w).norm(), 1e-12);
  EXPECT_NEAR(phi->sum(), 1.0, 1e-14);
  // A point outside has a negative coordinate.
  const auto outside =
      sinew::common::barycentric_coordinates(X, X.col(0) + 2.0 * (X.col(0) - X * w));
  ASSERT_TRUE(outside);
  EXPECT_LT(outside->minCoeff(), 0.0);
}

TEST(Tet4, BarycentricJacobianIsShapeGradients) {
  auto& gen = sinew::testing::rng();
  for (const Matrix3x4d& X : {random_tet(gen), nearly_flat_tet()}) {
    const auto rest = sinew::common::make_tet4_rest(X);
    const auto phi = [&X](const Eigen::VectorXd& p) -> Eigen::VectorXd {
      return *sinew::common::barycentric_coordinates(X, Eigen::Vector3d(p));
    };
    const Eigen::VectorXd p = X.rowwise().mean();
    EXPECT_TRUE(
        derivatives_match(rest.shape_gradients, sinew::testing::fd_jacobian(phi, p, 1e-5), 1e-8));
  }
}

}  // namespace
