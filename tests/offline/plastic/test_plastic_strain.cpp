// Tests of offline/plastic_strain: the s → Fp map of seed 003 (eq. 2), Fp⁻¹ and det Fp with their
// first and second derivatives with respect to s against finite differences, and the eigenvalue
// clamp of §3.4.

#include "offline/plastic/plastic_strain.hpp"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "tests/support/finite_difference.hpp"

namespace {

using sinew::common::unvec;
using sinew::common::vec;
using sinew::offline::EigenvalueClampStatus;
using sinew::offline::Matrix9x6d;
using sinew::offline::PlasticDerivativeOrder;
using sinew::offline::PlasticStrainStatus;
using sinew::offline::Vector6d;
using sinew::testing::derivatives_match;

// s of Q·diag(eigenvalues)·Qᵀ for a random rotation Q.
Vector6d symmetric_with_eigenvalues(const Eigen::Vector3d& eigenvalues, std::mt19937& gen) {
  const Eigen::Matrix3d Q = sinew::testing::random_rotation(gen);
  return sinew::offline::plastic_strain_vector(Q * eigenvalues.asDiagonal() * Q.transpose());
}

struct NamedStrain {
  std::string name;
  Vector6d s;
  double h;  // finite-difference step in s
};

// Seeded points: near identity, anisotropic, an eigenvalue near the 0.01 floor, nearly repeated
// eigenvalues, and an invertible but indefinite Fp (derivatives must hold there too).
std::vector<NamedStrain> test_strains() {
  auto& gen = sinew::testing::rng();
  std::vector<NamedStrain> points;
  for (int k = 0; k < 2; ++k) {
    points.push_back(
        {"near identity " + std::to_string(k),
         sinew::offline::identity_plastic_strain() + sinew::testing::random_vector(6, 0.2, gen),
         1e-5});
  }
  points.push_back(
      {"anisotropic 0.6/1.3/2.2", symmetric_with_eigenvalues({0.6, 1.3, 2.2}, gen), 1e-5});
  points.push_back({"eigenvalue 0.011 near the floor",
                    symmetric_with_eigenvalues({0.011, 1.0, 1.5}, gen), 1e-6});
  points.push_back({"nearly repeated eigenvalues",
                    symmetric_with_eigenvalues({0.8, 0.8 + 1e-7, 1.4}, gen), 1e-5});
  points.push_back(
      {"indefinite -0.7/0.9/1.2", symmetric_with_eigenvalues({-0.7, 0.9, 1.2}, gen), 1e-5});
  return points;
}

TEST(PlasticStrain, MatrixFollowsEquationTwo) {
  Vector6d s;
  s << 1, 2, 3, 4, 5, 6;
  Eigen::Matrix3d expected;
  expected << 1, 2, 3,  //
      2, 4, 5,          //
      3, 5, 6;
  EXPECT_EQ(sinew::offline::plastic_strain_matrix(s), expected);
  EXPECT_EQ(vec(expected), sinew::offline::plastic_strain_basis() * s);
  EXPECT_EQ(sinew::offline::plastic_strain_vector(expected), s);
  EXPECT_EQ(sinew::offline::plastic_strain_matrix(sinew::offline::identity_plastic_strain()),
            Eigen::Matrix3d::Identity());
  EXPECT_EQ(
      sinew::offline::plastic_strain_matrix(sinew::offline::scaled_identity_plastic_strain(1.5)),
      1.5 * Eigen::Matrix3d::Identity());
  const Eigen::VectorXd state = sinew::offline::identity_plastic_strains(3);
  ASSERT_EQ(state.size(), 18);
  EXPECT_EQ(state.segment<6>(12), sinew::offline::identity_plastic_strain());
  for (int k = 0; k < 6; ++k) {
    EXPECT_EQ(sinew::offline::plastic_strain_basis().col(k).sum(),
              sinew::offline::is_off_diagonal_component(k) ? 2.0 : 1.0);
  }
}

TEST(PlasticStrain, InverseAndDeterminantMatchDirectComputation) {
  for (const auto& [name, s, h] : test_strains()) {
    SCOPED_TRACE(name);
    const auto d = sinew::offline::plastic_strain_derivatives(s, PlasticDerivativeOrder::kValue);
    ASSERT_TRUE(d.invertible());
    const Eigen::Matrix3d Fp = sinew::offline::plastic_strain_matrix(s);
    EXPECT_LT((d.Fp_inv * Fp - Eigen::Matrix3d::Identity()).norm(), 1e-10);
    EXPECT_NEAR(d.det, Fp.determinant(), 1e-14);
  }
}

TEST(PlasticStrain, InverseDerivativesMatchFiniteDifferences) {
  const auto inverse = [](const Eigen::VectorXd& s) -> Eigen::VectorXd {
    return vec(
        sinew::offline::plastic_strain_derivatives(Vector6d(s), PlasticDerivativeOrder::kValue)
            .Fp_inv);
  };
  // ∂Fp⁻¹/∂s flattened column-major (54): its Jacobian's column l is d2Fp_inv_ds2[l] flattened.
  const auto first = [](const Eigen::VectorXd& s) -> Eigen::VectorXd {
    const Matrix9x6d D = sinew::offline::plastic_strain_derivatives(Vector6d(s)).dFp_inv_ds;
    return Eigen::Map<const Eigen::VectorXd>(D.data(), D.size());
  };
  for (const auto& [name, s, h] : test_strains()) {
    SCOPED_TRACE(name);
    const auto d = sinew::offline::plastic_strain_derivatives(s, PlasticDerivativeOrder::kSecond);
    ASSERT_TRUE(d.invertible());
    EXPECT_TRUE(derivatives_match(d.dFp_inv_ds, sinew::testing::fd_jacobian(inverse, s, h), 1e-7));
    Eigen::MatrixXd second(54, 6);
    for (int l = 0; l < 6; ++l) {
      second.col(l) = Eigen::Map<const Eigen::VectorXd>(d.d2Fp_inv_ds2[l].data(), 54);
    }
    EXPECT_TRUE(derivatives_match(second, sinew::testing::fd_jacobian(first, s, h), 1e-7));
    for (int l = 0; l < 6; ++l) {
      for (int k = 0; k < 6; ++k) {
        EXPECT_EQ(d.d2Fp_inv_ds2[l].col(k), d.d2Fp_inv_ds2[k].col(l)) << k << ", " << l;
      }
    }
  }
}

TEST(PlasticStrain, DeterminantDerivativesMatchFiniteDifferencesEvenWhenSingular) {
  auto points = test_strains();
  auto& gen = sinew::testing::rng();
  points.push_back({"singular 0/1/2", symmetric_with_eigenvalues({0.0, 1.0, 2.0}, gen), 1e-5});
  const auto det = [](const Eigen::VectorXd& s) {
    return sinew::offline::plastic_strain_derivatives(Vector6d(s), PlasticDerivativeOrder::kValue)
        .det;
  };
  const auto ddet = [](const Eigen::VectorXd& s) -> Eigen::VectorXd {
    return sinew::offline::plastic_strain_derivatives(Vector6d(s)).ddet_ds;
  };
  for (const auto& [name, s, h] : points) {
    SCOPED_TRACE(name);
    const auto d = sinew::offline::plastic_strain_derivatives(s, PlasticDerivativeOrder::kSecond);
    EXPECT_TRUE(derivatives_match(d.ddet_ds, sinew::testing::fd_gradient(det, s, h), 1e-8));
    EXPECT_TRUE(derivatives_match(d.d2det_ds2, sinew::testing::fd_jacobian(ddet, s, h), 1e-8));
    EXPECT_EQ(d.d2det_ds2, d.d2det_ds2.transpose());
  }
}

TEST(PlasticStrain, StatusClassifiesFp) {
  auto& gen = sinew::testing::rng();
  using sinew::offline::plastic_strain_derivatives;
  EXPECT_EQ(plastic_strain_derivatives(symmetric_with_eigenvalues({0.02, 1, 3}, gen)).status,
            PlasticStrainStatus::kPositiveDefinite);
  // det > 0 with two negative eigenvalues is still not positive definite.
  EXPECT_EQ(plastic_strain_derivatives(symmetric_with_eigenvalues({-0.5, -1, 3}, gen)).status,
            PlasticStrainStatus::kNotPositiveDefinite);
  EXPECT_EQ(plastic_strain_derivatives(symmetric_with_eigenvalues({-0.5, 1, 3}, gen)).status,
            PlasticStrainStatus::kNotPositiveDefinite);
  const auto singular = plastic_strain_derivatives(symmetric_with_eigenvalues({1e-15, 1, 3}, gen),
                                                   PlasticDerivativeOrder::kSecond);
  EXPECT_EQ(singular.status, PlasticStrainStatus::kSingular);
  EXPECT_TRUE(singular.Fp_inv.hasNaN());
  EXPECT_TRUE(singular.dFp_inv_ds.hasNaN());
  EXPECT_TRUE(singular.d2Fp_inv_ds2[3].hasNaN());
  EXPECT_TRUE(singular.ddet_ds.allFinite());
  EXPECT_EQ(plastic_strain_derivatives(Vector6d::Zero()).status, PlasticStrainStatus::kSingular);
  Vector6d bad = sinew::offline::identity_plastic_strain();
  bad[4] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(plastic_strain_derivatives(bad).status, PlasticStrainStatus::kNonFinite);
}

TEST(PlasticStrain, ClampRaisesSmallEigenvaluesToTheFloorAndKeepsEigenvectors) {
  auto& gen = sinew::testing::rng();
  const Eigen::Matrix3d Q = sinew::testing::random_rotation(gen);
  const Eigen::Vector3d lambda(-0.4, 0.003, 1.7);
  const Vector6d s = sinew::offline::plastic_strain_vector(Q * lambda.asDiagonal() * Q.transpose());
  const auto c = sinew::offline::clamp_plastic_strain_eigenvalues(s);
  ASSERT_EQ(c.status, EigenvalueClampStatus::kClamped);
  EXPECT_EQ(c.clamped_eigenvalues, 2);
  EXPECT_NEAR(c.min_eigenvalue, -0.4, 1e-12);
  const Eigen::Matrix3d expected =
      Q * Eigen::Vector3d(0.01, 0.01, 1.7).asDiagonal() * Q.transpose();
  EXPECT_LT((sinew::offline::plastic_strain_matrix(c.s) - expected).norm(), 1e-12);
  EXPECT_EQ(sinew::offline::plastic_strain_derivatives(c.s).status,
            PlasticStrainStatus::kPositiveDefinite);

  // Custom floor; an already valid Fp comes back bit for bit.
  const auto c2 = sinew::offline::clamp_plastic_strain_eigenvalues(s, 0.5);
  const Eigen::Matrix3d expected2 = Q * Eigen::Vector3d(0.5, 0.5, 1.7).asDiagonal() * Q.transpose();
  EXPECT_LT((sinew::offline::plastic_strain_matrix(c2.s) - expected2).norm(), 1e-12);
  const Vector6d good = symmetric_with_eigenvalues({0.011, 1.0, 2.0}, gen);
  const auto unchanged = sinew::offline::clamp_plastic_strain_eigenvalues(good);
  EXPECT_EQ(unchanged.status, EigenvalueClampStatus::kUnchanged);
  EXPECT_EQ(unchanged.s, good);
  EXPECT_EQ(unchanged.clamped_eigenvalues, 0);

  EXPECT_EQ(sinew::offline::clamp_plastic_strain_eigenvalues(good, 0.0).status,
            EigenvalueClampStatus::kInvalidFloor);
  Vector6d bad = good;
  bad[0] = std::numeric_limits<double>::infinity();
  EXPECT_EQ(sinew::offline::clamp_plastic_strain_eigenvalues(bad).status,
            EigenvalueClampStatus::kNonFinite);
}

TEST(PlasticStrain, ClampWholeStateInPlace) {
  auto& gen = sinew::testing::rng();
  Eigen::VectorXd state(18);
  state.segment<6>(0) = symmetric_with_eigenvalues({0.5, 1.0, 2.0}, gen);
  state.segment<6>(6) = symmetric_with_eigenvalues({-0.2, 1.0, 2.0}, gen);
  state.segment<6>(12) = symmetric_with_eigenvalues({0.3, 1.0, 2.0}, gen);
  const Eigen::VectorXd before = state;
  const auto summary = sinew::offline::clamp_plastic_state_eigenvalues(state);
  EXPECT_EQ(summary.status, EigenvalueClampStatus::kClamped);
  EXPECT_EQ(summary.clamped_tets, 1);
  EXPECT_NEAR(summary.min_eigenvalue, -0.2, 1e-12);
  EXPECT_EQ(state.segment<6>(0), before.segment<6>(0));
  EXPECT_EQ(state.segment<6>(12), before.segment<6>(12));
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(
      sinew::offline::plastic_strain_matrix(state.segment<6>(6)));
  EXPECT_NEAR(eigen.eigenvalues()[0], 0.01, 1e-12);

  Eigen::VectorXd wrong(7);
  wrong.setOnes();
  EXPECT_EQ(sinew::offline::clamp_plastic_state_eigenvalues(wrong).status,
            EigenvalueClampStatus::kInvalidSize);
  state[13] = std::numeric_limits<double>::quiet_NaN();
  const auto nan_summary = sinew::offline::clamp_plastic_state_eigenvalues(state);
  EXPECT_EQ(nan_summary.status, EigenvalueClampStatus::kNonFinite);
  ASSERT_TRUE(nan_summary.non_finite_tet);
  EXPECT_EQ(*nan_summary.non_finite_tet, 2);
}

}  // namespace
