// Finite-difference checks of the plane beam element (seed 000 appendix): p = ∂U/∂u and
// K_T = ∂p/∂u, at seeded random states including large rotations (past ±π) and near-degenerate
// chords, with and without pre-stress; plus invariances that would break with a wrong formula.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <cmath>

#include "common/beam/beam_element.hpp"
#include "tests/support/finite_difference.hpp"

namespace sinew::common {
namespace {

using sinew::testing::derivatives_match;
using sinew::testing::fd_gradient;
using sinew::testing::fd_jacobian;

struct ElementCase {
  Eigen::Vector2d X1, X2;
  BeamSection section;
  BeamPrestress prestress;
  Vector6d u;
};

double energy_of(const ElementCase& c, const Eigen::VectorXd& u) {
  double U = 0.0;
  evaluate_beam_element(make_beam_element_reference(c.X1, c.X2), c.section, c.prestress,
                        Vector6d(u), &U, nullptr, nullptr);
  return U;
}

Eigen::VectorXd force_of(const ElementCase& c, const Eigen::VectorXd& u) {
  Vector6d p;
  evaluate_beam_element(make_beam_element_reference(c.X1, c.X2), c.section, c.prestress,
                        Vector6d(u), nullptr, &p, nullptr);
  return p;
}

std::vector<ElementCase> cases() {
  auto& gen = sinew::testing::rng();
  std::vector<ElementCase> out;
  const BeamSection sections[] = {{1e3, 4e2, 2.0}, {5.0, 2.0, 0.7}, {1e6, 3e5, 1.0}};
  for (int k = 0; k < 12; ++k) {
    ElementCase c;
    c.X1 = sinew::testing::random_vector(2, 3.0, gen);
    c.X2 = c.X1 + sinew::testing::random_vector(2, 1.5, gen);
    c.section = sections[k % 3];
    if (k % 2) c.prestress = {0.3, -0.2, 0.1};
    c.u = sinew::testing::random_vector(6, 0.4, gen);
    if (k % 4 == 1) {  // rotations past ±π
      c.u[2] += 3.5;
      c.u[5] += 4.0;
    }
    if (k % 4 == 3) {  // near-degenerate: the current chord almost vanishes
      const Eigen::Vector2d D = c.X2 - c.X1;
      c.u.segment<2>(3) = c.u.segment<2>(0) - 0.999 * D;
    }
    out.push_back(c);
  }
  return out;
}

TEST(BeamElement, InternalForceIsEnergyGradient) {
  for (const auto& c : cases()) {
    const Eigen::VectorXd p = force_of(c, c.u);
    const Eigen::VectorXd fd =
        fd_gradient([&](const Eigen::VectorXd& u) { return energy_of(c, u); }, c.u, 1e-5);
    EXPECT_TRUE(derivatives_match(p, fd, 1e-7));
  }
}

TEST(BeamElement, TangentIsForceJacobian) {
  for (const auto& c : cases()) {
    Matrix6d K;
    evaluate_beam_element(make_beam_element_reference(c.X1, c.X2), c.section, c.prestress, c.u,
                          nullptr, nullptr, &K);
    const Eigen::MatrixXd fd =
        fd_jacobian([&](const Eigen::VectorXd& u) { return force_of(c, u); }, c.u, 1e-5);
    EXPECT_TRUE(derivatives_match(K, fd, 1e-7));
    EXPECT_LT((K - K.transpose()).norm(), 1e-9 * K.norm()) << "K_T must be symmetric";
  }
}

TEST(BeamElement, RigidMotionIsStrainFreeForAnyAngle) {
  const Eigen::Vector2d X1(0.3, -0.2), X2(1.1, 0.4);
  const auto ref = make_beam_element_reference(X1, X2);
  for (double angle : {0.3, 2.0, 3.1, -3.3, 6.283185307179586, 9.0}) {
    const Eigen::Rotation2Dd R(angle);
    const Eigen::Vector2d shift(5.0, -7.0);
    Vector6d u;
    u << R * X1 + shift - X1, angle, R * X2 + shift - X2, angle;
    const BeamStrains h = beam_strains(ref, u);
    EXPECT_NEAR(h.e, 0.0, 1e-14);
    EXPECT_NEAR(h.gamma, 0.0, 1e-14);
    EXPECT_NEAR(h.kappa, 0.0, 1e-14);
  }
}

TEST(BeamElement, StrainsMatchSeedDefinitions) {
  // Stretch by 10 % and shear by rotating the chord 0.2 rad while the sections stay at 0.05 rad:
  // 1 + e = (L/L₀) cos γ̄, γ = (L/L₀) sin γ̄ with γ̄ = ψ − θ̄ (seed 000, A-6).
  const Eigen::Vector2d X1(0.0, 0.0), X2(2.0, 0.0);
  const auto ref = make_beam_element_reference(X1, X2);
  const double psi = 0.2, theta1 = 0.02, theta2 = 0.08, stretch = 1.1;
  Vector6d u;
  u << 0, 0, theta1, 2.0 * stretch * std::cos(psi) - 2.0, 2.0 * stretch * std::sin(psi), theta2;
  const BeamStrains h = beam_strains(ref, u);
  const double gbar = psi - 0.5 * (theta1 + theta2);
  EXPECT_NEAR(h.e, stretch * std::cos(gbar) - 1.0, 1e-14);
  EXPECT_NEAR(h.gamma, stretch * std::sin(gbar), 1e-14);
  EXPECT_NEAR(h.kappa, (theta2 - theta1) / 2.0, 1e-14);
}

TEST(BeamElement, SmallDisplacementBendingMatchesLinearTimoshenko) {
  // Linearised at u = 0, a cantilever element with a tip force P has the linear Timoshenko
  // (reduced integration) stiffness: tip deflection v = P L³/(4EI) + P L/GA for one element.
  const auto ref = make_beam_element_reference({0, 0}, {1.0, 0});
  const BeamSection s{1e4, 50.0, 2.0};
  Matrix6d K;
  evaluate_beam_element(ref, s, {}, Vector6d::Zero(), nullptr, nullptr, &K);
  const Eigen::Matrix3d Kff = K.bottomRightCorner<3, 3>();
  const Eigen::Vector3d d = Kff.ldlt().solve(Eigen::Vector3d(0, 1e-3, 0));
  EXPECT_NEAR(d[1], 1e-3 * (1.0 / (4 * s.EI) + 1.0 / s.GA), 1e-12);
  EXPECT_NEAR(d[0], 0.0, 1e-15);
}

}  // namespace
}  // namespace sinew::common
