// Tests of common/material/stable_neo_hookean: parameters, small-strain limit, rest stability,
// inversion, ψ → P → ∂P/∂F and the tet element energy against finite differences, PSD projection.

#include "common/material/stable_neo_hookean.hpp"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "common/fem/tet4.hpp"
#include "tests/support/finite_difference.hpp"

namespace {

using sinew::common::HessianProjection;
using sinew::common::Matrix12d;
using sinew::common::Matrix3x4d;
using sinew::common::Matrix9d;
using sinew::common::StableNeoHookean;
using sinew::common::StableNeoHookeanParameters;
using sinew::common::unvec;
using sinew::common::vec;
using sinew::common::Vector9d;
using sinew::testing::derivatives_match;

StableNeoHookean material(double E = 1e4, double nu = 0.45) {
  const auto m = StableNeoHookean::create({E, nu});
  EXPECT_TRUE(m);
  return *m;
}

struct NamedMatrix {
  std::string name;
  Eigen::Matrix3d F;
};

std::vector<NamedMatrix> test_points() {
  auto& gen = sinew::testing::rng();
  const double pi = std::acos(-1.0);
  std::vector<NamedMatrix> points;
  for (int k = 0; k < 2; ++k) {
    points.push_back(
        {"near identity " + std::to_string(k),
         Eigen::Matrix3d::Identity() + unvec(sinew::testing::random_vector(9, 0.3, gen))});
  }
  points.push_back({"general", sinew::testing::matrix_with_singular_values({1.6, 1.1, 0.7}, gen)});
  points.push_back({"small singular value 0.05",
                    sinew::testing::matrix_with_singular_values({1.2, 0.9, 0.05}, gen)});
  points.push_back(
      {"inverted (det < 0)", sinew::testing::matrix_with_singular_values({1.1, 0.8, -0.3}, gen)});
  points.push_back({"rotation by pi - 1e-3, stretched",
                    sinew::testing::rotation_about({0.3, -1.0, 0.4}, pi - 1e-3) *
                        Eigen::Vector3d(1.05, 0.97, 1.02).asDiagonal()});
  points.push_back({"nearly collapsed", 0.05 * sinew::testing::random_rotation(gen)});
  return points;
}

TEST(StableNeoHookeanParameters, ValidationNamesTheField) {
  EXPECT_FALSE(StableNeoHookeanParameters{}.validate());
  const auto check = [](double E, double nu, const std::string& field) {
    const auto error = StableNeoHookeanParameters{E, nu}.validate();
    ASSERT_TRUE(error) << "E = " << E << ", nu = " << nu;
    EXPECT_NE(error->find(field), std::string::npos) << *error;
    EXPECT_FALSE(StableNeoHookean::create({E, nu}));
  };
  check(0.0, 0.3, "youngs_modulus");
  check(-5.0, 0.3, "youngs_modulus");
  check(std::numeric_limits<double>::quiet_NaN(), 0.3, "youngs_modulus");
  check(1e4, 0.5, "poisson_ratio");
  check(1e4, -1.0, "poisson_ratio");
  check(1e4, std::numeric_limits<double>::infinity(), "poisson_ratio");
  EXPECT_FALSE(StableNeoHookean::from_model_lame({1.0, 0.0}));
  EXPECT_FALSE(StableNeoHookean::from_model_lame({-1.0, 1.0}));
}

TEST(StableNeoHookean, LameReparameterisation) {
  const double E = 2e4;
  const double nu = 0.3;
  const auto linear = sinew::common::lame_from_young_poisson(E, nu);
  EXPECT_NEAR(linear.mu, E / 2.6, 1e-9);
  EXPECT_NEAR(linear.lambda, E * 0.3 / (1.3 * 0.4), 1e-9);
  const auto m = material(E, nu);
  EXPECT_NEAR(m.mu(), 4.0 / 3.0 * linear.mu, 1e-9);
  EXPECT_NEAR(m.lambda(), linear.lambda + 5.0 / 6.0 * linear.mu, 1e-9);
  EXPECT_NEAR(m.alpha(), 1.0 + 0.75 * m.mu() / m.lambda(), 1e-15);
}

TEST(StableNeoHookean, SmallStrainStressMatchesLinearElasticity) {
  // P(I + εG) = ε (2μ_L sym G + λ_L tr G I) + O(ε²) with μ_L, λ_L from the user's E, ν.
  auto& gen = sinew::testing::rng();
  for (const double nu : {-0.5, 0.0, 0.3, 0.45, 0.49}) {
    SCOPED_TRACE("nu = " + std::to_string(nu));
    const double E = 1e4;
    const auto m = material(E, nu);
    const auto lame = sinew::common::lame_from_young_poisson(E, nu);
    const Eigen::Matrix3d G = unvec(sinew::testing::random_vector(9, 1.0, gen));
    const Eigen::Matrix3d linear =
        lame.mu * (G + G.transpose()) + lame.lambda * G.trace() * Eigen::Matrix3d::Identity();
    const auto error = [&](double eps) {
      return (m.P(Eigen::Matrix3d::Identity() + eps * G) / eps - linear).norm() / linear.norm();
    };
    EXPECT_LT(error(1e-4), 1e-3);
    // The error is first order in ε (halving ε halves it): the O(1) terms agree exactly.
    EXPECT_NEAR(error(1e-4) / error(5e-5), 2.0, 0.05);
    // Equivalently, the tangent at the rest state is the linear elasticity tensor.
    EXPECT_LT((m.dPdF(Eigen::Matrix3d::Identity()) * vec(G) - vec(linear)).norm(),
              1e-12 * linear.norm());
  }
}

TEST(StableNeoHookean, RotationsAreEnergyAndStressFree) {
  auto& gen = sinew::testing::rng();
  const auto m = material();
  const double scale = m.mu() + m.lambda();
  const double pi = std::acos(-1.0);
  std::vector<Eigen::Matrix3d> rotations = {Eigen::Matrix3d::Identity(),
                                            sinew::testing::rotation_about({0, 0, 1}, pi),
                                            sinew::testing::rotation_about({1, 1, 0}, pi - 1e-6)};
  for (int k = 0; k < 5; ++k) rotations.push_back(sinew::testing::random_rotation(gen));
  for (const Eigen::Matrix3d& R : rotations) {
    EXPECT_NEAR(m.psi(R), 0.0, 1e-12 * scale);
    EXPECT_LT(m.P(R).norm(), 1e-12 * scale);
  }
  // ...while a stretch costs energy.
  EXPECT_GT(m.psi(Eigen::Vector3d(1.1, 1.0, 1.0).asDiagonal().toDenseMatrix()), 1e-4 * scale);
}

TEST(StableNeoHookean, ClosedFormValuesIncludingInversionAndCollapse) {
  const auto m = material();
  const double mu = m.mu(), lambda = m.lambda(), alpha = m.alpha();
  const double psi0 = 0.5 * lambda * (1 - alpha) * (1 - alpha) - 0.5 * mu * std::log(4.0);
  // F = −I (fully inverted): I_C = 3, J = −1, ψ = λ/2 ((1 + α)² − (1 − α)²) = 2λα.
  const Eigen::Matrix3d minus_I = -Eigen::Matrix3d::Identity();
  EXPECT_NEAR(m.psi(minus_I), 2.0 * lambda * alpha, 1e-12 * lambda);
  // F = 0 (collapsed to a point): I_C = 0, J = 0: ψ = −3μ/2 + λα²/2 − ψ₀, P = 0 − λα cof(0) = 0.
  const Eigen::Matrix3d zero = Eigen::Matrix3d::Zero();
  EXPECT_NEAR(m.psi(zero), -1.5 * mu + 0.5 * lambda * alpha * alpha - psi0, 1e-12 * lambda);
  EXPECT_TRUE(m.P(zero).allFinite());
  EXPECT_TRUE(m.dPdF(zero).allFinite());
  // F = s I: I_C = 3s², J = s³.
  const double s = 0.8;
  const double I_C = 3 * s * s, J = s * s * s;
  EXPECT_NEAR(m.psi(s * Eigen::Matrix3d::Identity()),
              0.5 * mu * (I_C - 3) + 0.5 * lambda * (J - alpha) * (J - alpha) -
                  0.5 * mu * std::log(I_C + 1) - psi0,
              1e-12 * lambda);
  // Inverted states have finite energy, stress and tangent, and the stress pushes back out.
  for (const auto& [name, F] : test_points()) {
    SCOPED_TRACE(name);
    EXPECT_TRUE(std::isfinite(m.psi(F)));
    EXPECT_TRUE(m.P(F).allFinite());
    EXPECT_TRUE(m.dPdF(F).allFinite());
  }
  EXPECT_GT(m.psi(minus_I), m.psi(Eigen::Matrix3d::Identity()));
}

TEST(StableNeoHookean, StressMatchesFiniteDifferencesOfEnergy) {
  const auto m = material();
  const auto psi = [&m](const Eigen::VectorXd& f) { return m.psi(unvec(f)); };
  for (const auto& [name, F] : test_points()) {
    SCOPED_TRACE(name);
    EXPECT_TRUE(
        derivatives_match(vec(m.P(F)), sinew::testing::fd_gradient(psi, vec(F), 1e-4), 1e-8));
  }
}

TEST(StableNeoHookean, TangentMatchesFiniteDifferencesOfStress) {
  const auto m = material();
  const auto P = [&m](const Eigen::VectorXd& f) -> Eigen::VectorXd { return vec(m.P(unvec(f))); };
  for (const auto& [name, F] : test_points()) {
    SCOPED_TRACE(name);
    const Matrix9d dPdF = m.dPdF(F);
    EXPECT_TRUE(derivatives_match(dPdF, sinew::testing::fd_jacobian(P, vec(F), 1e-4), 1e-8));
    EXPECT_LT((dPdF - dPdF.transpose()).norm(), 1e-14 * dPdF.norm());
  }
}

// Element tests: rest tets and deformed positions.
struct ElementCase {
  std::string name;
  Matrix3x4d rest;
  Matrix3x4d x;
  double h;  // finite-difference step, metres (scaled to the element's thinnest dimension)
};

std::vector<ElementCase> element_cases() {
  auto& gen = sinew::testing::rng();
  std::vector<ElementCase> cases;
  Matrix3x4d X;
  X << 0.0, 1.0, 0.1, 0.2,  //
      0.0, 0.2, 0.9, 0.1,   //
      0.0, 0.1, 0.2, 1.1;
  const auto noise = [&gen](double scale) {
    return Matrix3x4d(
        Eigen::Map<const Matrix3x4d>(sinew::testing::random_vector(12, scale, gen).data()));
  };
  const Eigen::Matrix3d A =
      Eigen::Matrix3d::Identity() + unvec(sinew::testing::random_vector(9, 0.3, gen));
  cases.push_back({"general", X, A * X + noise(0.1), 1e-5});
  Matrix3x4d inverted = X;
  inverted.col(3) = X.col(0) - 0.3 * (X.col(3) - X.col(0));  // apex pushed through the base
  cases.push_back({"inverted", X, inverted + noise(0.02), 1e-5});
  const Eigen::Matrix3d squash = sinew::testing::matrix_with_singular_values({1.1, 0.9, 0.05}, gen);
  cases.push_back({"small singular value 0.05", X, squash * X + noise(0.002), 1e-6});
  Matrix3x4d flat;
  flat << 0.0, 1.0, 0.2, 0.4,  //
      0.0, 0.1, 1.0, 0.4,      //
      0.0, 0.0, 0.0, 1e-3;
  cases.push_back({"nearly flat rest tet", flat, A * flat + noise(2e-4), 1e-8});
  const Eigen::Matrix3d half_turn =
      sinew::testing::rotation_about({0.2, 1.0, -0.7}, std::acos(-1.0) - 1e-3);
  cases.push_back({"rotated by pi - 1e-3", X, half_turn * (A * X) + noise(0.05), 1e-5});
  return cases;
}

TEST(StableNeoHookeanTet, GradientAndHessianMatchFiniteDifferences) {
  const auto m = material();
  for (const auto& c : element_cases()) {
    SCOPED_TRACE(c.name);
    const auto rest = sinew::common::make_tet4_rest(c.rest);
    ASSERT_EQ(rest.status, sinew::common::Tet4Status::kValid);
    const auto energy = [&](const Eigen::VectorXd& x) {
      return sinew::common::tet_elastic_energy(m, rest, Eigen::Map<const Matrix3x4d>(x.data()));
    };
    const auto gradient = [&](const Eigen::VectorXd& x) -> Eigen::VectorXd {
      return sinew::common::tet_elastic_gradient(m, rest, Eigen::Map<const Matrix3x4d>(x.data()));
    };
    const Eigen::VectorXd x = sinew::common::to_element_dofs(c.x);
    const sinew::common::Vector12d g = gradient(x);
    EXPECT_TRUE(derivatives_match(g, sinew::testing::fd_gradient(energy, x, c.h), 1e-7));
    const Matrix12d H = sinew::common::tet_elastic_hessian(m, rest, c.x);
    EXPECT_TRUE(derivatives_match(H, sinew::testing::fd_jacobian(gradient, x, c.h), 1e-7));
    // Translation invariance: the vertex forces sum to zero.
    EXPECT_LT(g.reshaped(3, 4).rowwise().sum().norm(), 1e-10 * g.norm());
    // evaluate_tet_elastic gives the same three results in one call.
    double e = 0.0;
    sinew::common::Vector12d g2;
    Matrix12d H2;
    sinew::common::evaluate_tet_elastic(m, rest, c.x, &e, &g2, &H2);
    EXPECT_EQ(e, energy(x));
    EXPECT_EQ(g2, g);
    EXPECT_EQ(H2, H);
  }
}

double min_eigenvalue(const Matrix12d& H) {
  return Eigen::SelfAdjointEigenSolver<Matrix12d>(H).eigenvalues().minCoeff();
}

TEST(StableNeoHookeanTet, ProjectedHessianIsPositiveSemiDefinite) {
  const auto m = material();
  const auto cases = element_cases();
  int indefinite_cases = 0;
  for (const auto& c : cases) {
    SCOPED_TRACE(c.name);
    const auto rest = sinew::common::make_tet4_rest(c.rest);
    const Matrix12d H = sinew::common::tet_elastic_hessian(m, rest, c.x);
    const double scale = H.norm();
    if (min_eigenvalue(H) < -1e-6 * scale) ++indefinite_cases;
    for (const auto projection :
         {HessianProjection::kProjectDPdF, HessianProjection::kProjectElement}) {
      const Matrix12d H_psd = sinew::common::tet_elastic_hessian(m, rest, c.x, projection);
      EXPECT_GT(min_eigenvalue(H_psd), -1e-10 * scale);
      EXPECT_LT((H_psd - H_psd.transpose()).norm(), 1e-14 * scale);
    }
    // The nearest PSD matrix only lifts negative eigenvalues: H₊ − H is PSD.
    const Matrix12d lift =
        sinew::common::tet_elastic_hessian(m, rest, c.x, HessianProjection::kProjectElement) - H;
    EXPECT_GT(min_eigenvalue(lift), -1e-10 * scale);
  }
  EXPECT_GE(indefinite_cases, 2);  // the check above was not vacuous
}

TEST(StableNeoHookeanTet, ProjectionLeavesPositiveSemiDefiniteHessianUnchanged) {
  auto& gen = sinew::testing::rng();
  const auto m = material();
  Matrix3x4d X;
  X << 0.0, 1.0, 0.1, 0.2,  //
      0.0, 0.2, 0.9, 0.1,   //
      0.0, 0.1, 0.2, 1.1;
  const auto rest = sinew::common::make_tet4_rest(X);
  // Slightly stretched, 1 < J < α, and rotated: ∂P/∂F is positive definite there (at J = 1 the
  // twist modes are exactly zero; far from it, λ(J − α)∂²J/∂F² makes ∂P/∂F indefinite).
  const Eigen::Matrix3d F = sinew::testing::random_rotation(gen) *
                            Eigen::Vector3d(1.03, 1.02, 1.01).asDiagonal().toDenseMatrix();
  ASSERT_LT(F.determinant(), m.alpha());
  ASSERT_GT(Eigen::SelfAdjointEigenSolver<Matrix9d>(m.dPdF(F)).eigenvalues().minCoeff(), 0.0);
  const Matrix3x4d x = F * X;
  const Matrix12d H = sinew::common::tet_elastic_hessian(m, rest, x);
  // Bit for bit with the 9x9 projection (nothing to clamp); to round-off with the 12x12 one,
  // whose three translation eigenvalues are zero up to round-off.
  EXPECT_EQ(sinew::common::tet_elastic_hessian(m, rest, x, HessianProjection::kProjectDPdF), H);
  EXPECT_LT((sinew::common::tet_elastic_hessian(m, rest, x, HessianProjection::kProjectElement) - H)
                .norm(),
            1e-10 * H.norm());
}

TEST(StableNeoHookeanTet, ProjectToPsdClampsNegativeEigenvalues) {
  auto& gen = sinew::testing::rng();
  const Eigen::Matrix<double, 9, 1> eigenvalues =
      (Eigen::Matrix<double, 9, 1>() << -3, -1, 0, 0.5, 1, 2, 3, 4, 5).finished();
  const Matrix9d Q =
      Eigen::HouseholderQR<Matrix9d>(
          unvec(Vector9d::Ones()).replicate<3, 3>() +
          Eigen::Map<const Matrix9d>(sinew::testing::random_vector(81, 1.0, gen).data()))
          .householderQ();
  const Matrix9d A = Q * eigenvalues.asDiagonal() * Q.transpose();
  const Matrix9d expected = Q * eigenvalues.cwiseMax(0.0).asDiagonal() * Q.transpose();
  EXPECT_LT((sinew::common::project_to_psd(A) - expected).norm(), 1e-12 * A.norm());
}

}  // namespace
