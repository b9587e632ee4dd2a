// Tests of common/geometry/polar_decomposition: the decomposition itself and its first and second
// derivatives (seed 003, eqs. 21–24 and 47–52) against finite differences.

#include "common/geometry/polar_decomposition.hpp"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <cmath>
#include <string>
#include <vector>

#include "tests/support/finite_difference.hpp"

namespace {

using sinew::common::Matrix9d;
using sinew::common::PolarDerivativeOrder;
using sinew::common::PolarStatus;
using sinew::common::unvec;
using sinew::common::vec;
using sinew::common::Vector9d;
using sinew::testing::derivatives_match;

struct NamedMatrix {
  std::string name;
  Eigen::Matrix3d F;
};

// Seeded points with det F > 0, including the near-degenerate ones the solvers will meet.
std::vector<NamedMatrix> test_points() {
  auto& gen = sinew::testing::rng();
  const double pi = std::acos(-1.0);
  std::vector<NamedMatrix> points;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Matrix3d G = unvec(sinew::testing::random_vector(9, 0.3, gen));
    points.push_back({"near identity " + std::to_string(k), Eigen::Matrix3d::Identity() + G});
  }
  points.push_back(
      {"general stretch", sinew::testing::matrix_with_singular_values({1.7, 0.9, 0.6}, gen)});
  points.push_back({"small singular value 0.05",
                    sinew::testing::matrix_with_singular_values({1.2, 0.8, 0.05}, gen)});
  points.push_back({"nearly repeated singular values",
                    sinew::testing::matrix_with_singular_values({1.0, 1.0 + 1e-6, 0.7}, gen)});
  const Eigen::Vector3d axis = sinew::testing::random_vector(3, 1.0, gen);
  points.push_back({"rotation by pi - 1e-3, stretched",
                    sinew::testing::rotation_about(axis, pi - 1e-3) *
                        (Eigen::Matrix3d::Identity() +
                         0.05 * unvec(sinew::testing::random_vector(9, 1.0, gen)))});
  points.push_back({"exact rotation by pi", sinew::testing::rotation_about(axis, pi)});
  return points;
}

TEST(PolarDecomposition, FactorsAreRotationAndSymmetricPositiveDefinite) {
  for (const auto& [name, F] : test_points()) {
    SCOPED_TRACE(name);
    const auto polar = sinew::common::polar_decomposition(F);
    ASSERT_EQ(polar.status, PolarStatus::kSuccess);
    EXPECT_LT((polar.R.transpose() * polar.R - Eigen::Matrix3d::Identity()).norm(), 1e-13);
    EXPECT_NEAR(polar.R.determinant(), 1.0, 1e-13);
    EXPECT_EQ(polar.S, polar.S.transpose());
    EXPECT_LT((polar.R * polar.S - F).norm(), 1e-13 * F.norm());
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(polar.S);
    EXPECT_GT(eigen.eigenvalues().minCoeff(), 0.0);
  }
}

TEST(PolarDecomposition, RotationOfStretchedRotationIsRecovered) {
  auto& gen = sinew::testing::rng();
  const Eigen::Matrix3d R0 = sinew::testing::random_rotation(gen);
  const Eigen::Matrix3d V = sinew::testing::random_rotation(gen);
  const Eigen::Matrix3d S0 = V * Eigen::Vector3d(2.0, 0.5, 0.1).asDiagonal() * V.transpose();
  const auto polar = sinew::common::polar_decomposition(R0 * S0);
  EXPECT_LT((polar.R - R0).norm(), 1e-12);
  EXPECT_LT((polar.S - S0).norm(), 1e-12);
}

TEST(PolarDecomposition, NonPositiveDeterminantIsReportedNotThrown) {
  auto& gen = sinew::testing::rng();
  const Eigen::Matrix3d F = sinew::testing::matrix_with_singular_values({1.5, 1.0, -0.4}, gen);
  ASSERT_LT(F.determinant(), 0.0);
  const auto polar = sinew::common::polar_decomposition(F);
  EXPECT_EQ(polar.status, PolarStatus::kNonPositiveDeterminant);
  // The factors are still usable: a proper rotation and a symmetric, indefinite stretch.
  EXPECT_NEAR(polar.R.determinant(), 1.0, 1e-13);
  EXPECT_LT((polar.R * polar.S - F).norm(), 1e-13 * F.norm());
  EXPECT_EQ(polar.S, polar.S.transpose());
  EXPECT_LT(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(polar.S).eigenvalues().minCoeff(), 0.0);

  const auto derivatives = sinew::common::polar_decomposition_derivatives(F);
  EXPECT_EQ(derivatives.status, PolarStatus::kNonPositiveDeterminant);
  EXPECT_EQ(derivatives.dRdF, Matrix9d::Zero());

  const Eigen::Matrix3d singular =
      sinew::testing::matrix_with_singular_values({1.0, 0.5, 0.0}, gen);
  EXPECT_NE(sinew::common::polar_decomposition_derivatives(singular).status, PolarStatus::kSuccess);

  Eigen::Matrix3d nan_matrix = Eigen::Matrix3d::Identity();
  nan_matrix(1, 2) = std::nan("");
  EXPECT_EQ(sinew::common::polar_decomposition(nan_matrix).status, PolarStatus::kNonFinite);
  EXPECT_EQ(sinew::common::polar_decomposition_derivatives(nan_matrix).status,
            PolarStatus::kNonFinite);
}

TEST(PolarDecomposition, KroneckerSumMapsToSylvesterOperator) {
  // seed 003, eq. 23: (S ⊕ S) vec(X) = vec(S X + X S) for symmetric S.
  auto& gen = sinew::testing::rng();
  const Eigen::Matrix3d A = unvec(sinew::testing::random_vector(9, 1.0, gen));
  const Eigen::Matrix3d S = A + A.transpose();
  const Eigen::Matrix3d X = unvec(sinew::testing::random_vector(9, 1.0, gen));
  EXPECT_LT((sinew::common::kronecker_sum(S) * vec(X) - vec(S * X + X * S)).norm(),
            1e-14 * S.norm() * X.norm());
}

TEST(PolarDecomposition, RotationDerivativeAtDiagonalStretchMatchesClosedForm) {
  // At F = diag(s), R = I and dR = Ω skew with (E − Eᵀ)_ij = Ω_ij (s_i + s_j); for E = e0 e1ᵀ:
  // Ω_01 = −Ω_10 = 1 / (s0 + s1).
  const Eigen::Vector3d s(1.5, 0.7, 0.3);
  const auto d = sinew::common::polar_decomposition_derivatives(s.asDiagonal().toDenseMatrix());
  ASSERT_EQ(d.status, PolarStatus::kSuccess);
  Eigen::Matrix3d expected = Eigen::Matrix3d::Zero();
  expected(0, 1) = 1.0 / (s(0) + s(1));
  expected(1, 0) = -expected(0, 1);
  EXPECT_LT((unvec(d.dRdF.col(sinew::common::vec_index(0, 1))) - expected).norm(), 1e-14);
}

// Finite differences of the factors as functions of vec(F).
Eigen::VectorXd vec_R(const Eigen::VectorXd& f) {
  return vec(sinew::common::polar_decomposition(unvec(f)).R);
}
Eigen::VectorXd vec_S(const Eigen::VectorXd& f) {
  return vec(sinew::common::polar_decomposition(unvec(f)).S);
}
Eigen::VectorXd flat_dRdF(const Eigen::VectorXd& f) {
  const Matrix9d d = sinew::common::polar_decomposition_derivatives(unvec(f)).dRdF;
  return Eigen::Map<const Eigen::VectorXd>(d.data(), 81);
}
Eigen::VectorXd flat_dSdF(const Eigen::VectorXd& f) {
  const Matrix9d d = sinew::common::polar_decomposition_derivatives(unvec(f)).dSdF;
  return Eigen::Map<const Eigen::VectorXd>(d.data(), 81);
}
// d2[j] as an 81x9 matrix whose column j is the column-major flattening of d2[j].
Eigen::MatrixXd stack(const std::array<Matrix9d, 9>& d2) {
  Eigen::MatrixXd out(81, 9);
  for (int j = 0; j < 9; ++j) out.col(j) = Eigen::Map<const Eigen::VectorXd>(d2[j].data(), 81);
  return out;
}

constexpr double kStep = 1e-4;

TEST(PolarDecomposition, FirstDerivativesMatchFiniteDifferences) {
  for (const auto& [name, F] : test_points()) {
    SCOPED_TRACE(name);
    const auto d = sinew::common::polar_decomposition_derivatives(F);
    ASSERT_EQ(d.status, PolarStatus::kSuccess);
    const Vector9d f = vec(F);
    EXPECT_TRUE(derivatives_match(d.dRdF, sinew::testing::fd_jacobian(vec_R, f, kStep), 1e-7));
    EXPECT_TRUE(derivatives_match(d.dSdF, sinew::testing::fd_jacobian(vec_S, f, kStep), 1e-7));
  }
}

TEST(PolarDecomposition, SecondDerivativesMatchFiniteDifferencesOfFirst) {
  for (const auto& [name, F] : test_points()) {
    SCOPED_TRACE(name);
    const auto d = sinew::common::polar_decomposition_derivatives(F, PolarDerivativeOrder::kSecond);
    ASSERT_EQ(d.status, PolarStatus::kSuccess);
    const Vector9d f = vec(F);
    EXPECT_TRUE(
        derivatives_match(stack(d.d2RdF2), sinew::testing::fd_jacobian(flat_dRdF, f, kStep), 1e-6));
    EXPECT_TRUE(
        derivatives_match(stack(d.d2SdF2), sinew::testing::fd_jacobian(flat_dSdF, f, kStep), 1e-6));
    // First-order results are the same whichever order is requested.
    EXPECT_EQ(d.dRdF, sinew::common::polar_decomposition_derivatives(F).dRdF);
  }
}

}  // namespace
