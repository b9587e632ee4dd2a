// Tests of offline/free_equilibrium (seed 003 §3.6, eqs. 18–20 in Ipopt): Ipopt's own derivative
// checker finds no error in the gradient, the constraint Jacobian (centroid and polar rotation)
// or the Hessian of the Lagrangian (K and the polar decomposition's second derivatives) at a
// deformed, rotated start; the solve converges to f_e = 0 with the constraints met, and agrees
// with the route the registration takes (pinned Newton equilibrium + RigidStabilisation::move_to).

#include "offline/equilibrium/free_equilibrium.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

#include "offline/equilibrium/equilibrium.hpp"
#include "tests/support/offline_fixtures.hpp"

namespace sinew::offline {
namespace {

struct StabilisedBlock {
  testing::FreeBlock block;
  std::optional<RigidStabilisation> stabilisation;
  RigidFrame frame;
  StabilisedBlock() {
    // Marker points: a few vertices on the block's faces.
    std::vector<EmbeddedPoint> points;
    for (int v : {0, 3, 5, 14, 20, 26, 33, 35})
      points.push_back(testing::at_vertex(block.mesh.tets, v));
    stabilisation = RigidStabilisation::create(block.mesh.tets, block.energy->rest_dofs(), points);
    frame.R = Eigen::AngleAxisd(1.2, Eigen::Vector3d(1, -1, 2).normalized()).toRotationMatrix();
    frame.t = Eigen::Vector3d(0.3, -0.1, 0.2);
  }
};

TEST(FreeEquilibrium, IpoptDerivativeCheckerFindsNoErrors) {
  StabilisedBlock setup;
  ASSERT_TRUE(setup.stabilisation.has_value());
  // A deformed start away from the frame, so every constraint term and the polar Hessian are
  // exercised (not at the identity).
  Eigen::VectorXd x = setup.block.energy->rest_dofs();
  RigidTransform{Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()).toRotationMatrix(), {0.1, 0, 0}}
      .apply_to_dofs(x);
  std::mt19937 rng(4);
  std::normal_distribution<double> noise(0.0, 0.003);
  for (Eigen::Index i = 0; i < x.size(); ++i) x[i] += noise(rng);
  FreeEquilibriumOptions options;
  options.derivative_test = IpoptDerivativeTest::kSecondOrder;
  options.max_iterations = 0;
  const FreeEquilibriumSummary summary = solve_free_equilibrium(
      *setup.block.energy, *setup.stabilisation, setup.frame, setup.block.s, x, options);
  ASSERT_TRUE(summary.derivative_test_errors.has_value());
  EXPECT_EQ(*summary.derivative_test_errors, 0);
}

TEST(FreeEquilibrium, IpoptSolveMatchesPinnedNewtonMovedToTheFrame) {
  StabilisedBlock setup;
  ASSERT_TRUE(setup.stabilisation.has_value());
  Eigen::VectorXd x_ipopt = setup.block.energy->rest_dofs();
  const FreeEquilibriumSummary summary = solve_free_equilibrium(
      *setup.block.energy, *setup.stabilisation, setup.frame, setup.block.s, x_ipopt);
  EXPECT_TRUE(summary.converged())
      << "ipopt " << summary.ipopt_return_code.value_or(-1) << " residual " << summary.residual_norm
      << " constraints " << summary.constraint_violation;
  EXPECT_LE(summary.constraint_violation, 1e-10);
  auto none =
      PointConstraints::create(setup.block.mesh.rest_positions.rows(), setup.block.mesh.tets, {});
  EquilibriumOptions tight;
  tight.force_tolerance = 1e-10;
  auto newton = EquilibriumSolver::create(*setup.block.energy, *none, tight);
  Eigen::VectorXd x_newton = setup.block.energy->rest_dofs();
  ASSERT_TRUE(newton->solve(setup.block.s, x_newton).converged());
  ASSERT_TRUE(setup.stabilisation->move_to(setup.frame, x_newton));
  const double scale = (x_newton - setup.block.energy->rest_dofs()).lpNorm<Eigen::Infinity>();
  EXPECT_GT(scale, 0.1);  // far from the template: rotated, translated and deformed
  EXPECT_LT((x_ipopt - x_newton).lpNorm<Eigen::Infinity>(), 1e-6 * scale);
}

}  // namespace
}  // namespace sinew::offline
