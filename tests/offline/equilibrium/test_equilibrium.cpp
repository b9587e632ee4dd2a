// Tests of offline/equilibrium: the static equilibrium f_e(Fp(s), x) + f_a(x) = 0 of seed 003
// (eq. 4) as the minimiser of E + E_a. (a) Newton/CHOLMOD and Ipopt reach the same x under
// stretching and rotating attachments; (b) a uniform plastic strain Fp = c·I held by weak springs
// on one face grows the body by (c − 1)·length; (c) a warm start at the solution needs at most
// one iteration; (d) bad inputs and options are statuses; (e) Ipopt's derivative checker finds no
// error in the gradient and Hessian.

#include "offline/equilibrium/equilibrium.hpp"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "common/fem/sparse_assembly.hpp"
#include "common/material/stable_neo_hookean.hpp"
#include "offline/constraints/constraints.hpp"
#include "offline/plastic/plastic_elastic_energy.hpp"
#include "offline/plastic/plastic_strain.hpp"
#include "tests/support/finite_difference.hpp"
#include "tests/support/offline_fixtures.hpp"
#include "tests/support/tet_mesh_fixtures.hpp"

namespace sinew::offline {
namespace {

using testing::at_vertex;
using testing::soft_tissue;

struct Scene {
  testing::TetMesh mesh;
  std::optional<PlasticElasticEnergy> energy;
  std::optional<PointConstraints> attachments;
};

// Box mesh with attachments from a rule: target(v, X) returns the target of vertex v (rest X) or
// std::nullopt for no attachment.
template <typename Target>
Scene make_scene(int nx, int ny, int nz, double h, double weight, const Target& target) {
  Scene scene;
  scene.mesh = testing::make_box_mesh(nx, ny, nz, h);
  scene.energy =
      PlasticElasticEnergy::create(scene.mesh.rest_positions, scene.mesh.tets, soft_tissue());
  EXPECT_TRUE(scene.energy.has_value());
  std::vector<PointConstraint> constraints;
  for (int v = 0; v < scene.mesh.rest_positions.rows(); ++v) {
    const Eigen::Vector3d X = scene.mesh.rest_positions.row(v).transpose();
    const std::optional<Eigen::Vector3d> y = target(v, X);
    if (!y) continue;
    PointConstraint c;
    c.kind = ConstraintKind::kAttachment;
    c.point = at_vertex(scene.mesh.tets, v);
    c.target = *y;
    c.weight = weight;
    constraints.push_back(c);
  }
  scene.attachments =
      PointConstraints::create(scene.mesh.rest_positions.rows(), scene.mesh.tets, constraints);
  EXPECT_TRUE(scene.attachments.has_value());
  return scene;
}

// 3x2x2 cubes of 0.1 m: face x = 0 held at rest, face x = 0.3 m pulled to a stretched (1.15 along
// x) and rotated (15° about x) position. Stiff springs (c = 1e4 N/m vs μh ≈ 360 N/m).
Scene stretched_rotated_scene() {
  const double length = 0.3;
  const Eigen::Matrix3d R =
      testing::rotation_about(Eigen::Vector3d::UnitX(), 15.0 * EIGEN_PI / 180);
  const Eigen::Vector3d axis(0.0, 0.1, 0.1);  // rotate the far face about the box's centre line
  return make_scene(3, 2, 2, 0.1, 1e4,
                    [&](int, const Eigen::Vector3d& X) -> std::optional<Eigen::Vector3d> {
                      if (X.x() < 1e-9) return X;
                      if (X.x() > length - 1e-9) {
                        Eigen::Vector3d p = X - axis;
                        p.x() = 1.15 * length;
                        return axis + R * p;
                      }
                      return std::nullopt;
                    });
}

EquilibriumOptions options_for(EquilibriumMethod method) {
  EquilibriumOptions o;
  o.method = method;
  return o;
}

TEST(Equilibrium, NewtonAndIpoptAgreeUnderStretchedRotatedAttachments) {
  Scene scene = stretched_rotated_scene();
  const Eigen::VectorXd s = identity_plastic_strains(scene.energy->num_tets());
  const Eigen::VectorXd rest = scene.energy->rest_dofs();

  std::string error;
  auto newton = EquilibriumSolver::create(*scene.energy, *scene.attachments,
                                          options_for(EquilibriumMethod::kNewton), &error);
  ASSERT_TRUE(newton.has_value()) << error;
  auto ipopt = EquilibriumSolver::create(*scene.energy, *scene.attachments,
                                         options_for(EquilibriumMethod::kIpopt), &error);
  ASSERT_TRUE(ipopt.has_value()) << error;

  Eigen::VectorXd x_newton = rest;
  const EquilibriumSummary sn = newton->solve(s, x_newton);
  ASSERT_EQ(sn.status, EquilibriumStatus::kConverged) << sn.full_report();
  Eigen::VectorXd x_ipopt = rest;
  const EquilibriumSummary si = ipopt->solve(s, x_ipopt);
  ASSERT_EQ(si.status, EquilibriumStatus::kConverged) << si.full_report();
  EXPECT_GT(sn.iterations, 1);
  EXPECT_GT(sn.factorisations, 0);
  ASSERT_TRUE(si.ipopt_return_code.has_value());

  // The same equilibrium, to 1e-6 relative to the displacement.
  const double displacement = (x_newton - rest).norm();
  EXPECT_GT(displacement, 0.01);
  EXPECT_LT((x_newton - x_ipopt).norm(), 1e-6 * displacement) << sn.brief_report() << "\n"
                                                              << si.brief_report();

  // f_e + f_a below the tolerance, evaluated independently of the summaries.
  for (const Eigen::VectorXd* x : {&x_newton, &x_ipopt}) {
    Eigen::VectorXd f(x->size());
    ASSERT_TRUE(newton->net_force(s, *x, f));
    ASSERT_TRUE(sn.residual_norm.has_value());
    EXPECT_LE(f.lpNorm<Eigen::Infinity>(),
              newton->options().force_tolerance * std::max(sn.force_scale, si.force_scale));
    // Not a trivial balance: the springs carry real load.
    Eigen::VectorXd fa(x->size());
    scene.attachments->gradient(*x, fa);
    EXPECT_GT(fa.lpNorm<Eigen::Infinity>(), 1e6 * f.lpNorm<Eigen::Infinity>());
  }
  EXPECT_NEAR(*sn.energy, *si.energy, 1e-9 * std::abs(*sn.energy));
  EXPECT_FALSE(sn.brief_report().empty());
  EXPECT_NE(sn.full_report().find("converged"), std::string::npos);
}

TEST(Equilibrium, UniformPlasticStrainGrowsTheBody) {
  // Fp = c·I: the stress-free shape is the template scaled by c. Weak springs (c_k ≪ μh) on the
  // vertices of face x = 0 only fix the rigid motion; the far face then sits at ≈ c·length.
  const double c = 1.5;
  const double length = 0.4;
  const double h = 0.1;
  const common::StableNeoHookean material = soft_tissue();
  const double weak = 0.01 * material.mu() * h;
  Scene scene = make_scene(4, 2, 2, h, weak,
                           [&](int, const Eigen::Vector3d& X) -> std::optional<Eigen::Vector3d> {
                             if (X.x() < 1e-9) return X;
                             return std::nullopt;
                           });
  Eigen::VectorXd s(scene.energy->num_plastic_dofs());
  for (Eigen::Index t = 0; t < scene.energy->num_tets(); ++t) {
    s.segment<6>(6 * t) = scaled_identity_plastic_strain(c);
  }
  for (const EquilibriumMethod method : {EquilibriumMethod::kNewton, EquilibriumMethod::kIpopt}) {
    auto solver = EquilibriumSolver::create(*scene.energy, *scene.attachments, options_for(method));
    ASSERT_TRUE(solver.has_value());
    Eigen::VectorXd x = scene.energy->rest_dofs();
    const EquilibriumSummary summary = solver->solve(s, x);
    ASSERT_EQ(summary.status, EquilibriumStatus::kConverged) << summary.full_report();

    const Eigen::MatrixXd X = scene.mesh.rest_positions;
    const Eigen::MatrixXd P = common::to_positions(x);
    double near_face = 0.0;
    double far_face = 0.0;
    int n_near = 0;
    int n_far = 0;
    for (Eigen::Index v = 0; v < X.rows(); ++v) {
      if (X(v, 0) < 1e-9) {
        near_face += P(v, 0);
        ++n_near;
      } else if (X(v, 0) > length - 1e-9) {
        far_face += P(v, 0);
        ++n_far;
      }
    }
    near_face /= n_near;
    far_face /= n_far;
    const double growth = far_face - length;  // how far the far face moved out
    EXPECT_NEAR(growth, (c - 1.0) * length, 0.03 * (c - 1.0) * length) << to_string(method);
    EXPECT_NEAR(far_face - near_face, c * length, 0.03 * c * length) << to_string(method);
    // The body is (nearly) stress free: its energy is small against the compressed start.
    ASSERT_TRUE(
        scene.energy->evaluate(s, scene.energy->rest_dofs(), PlasticEnergyRequest{}).valid());
    EXPECT_LT(*summary.energy, 1e-2 * scene.energy->energy()) << to_string(method);
  }
}

TEST(Equilibrium, WarmStartAtTheSolutionTakesAtMostOneIteration) {
  Scene scene = stretched_rotated_scene();
  const Eigen::VectorXd s = identity_plastic_strains(scene.energy->num_tets());
  for (const EquilibriumMethod method : {EquilibriumMethod::kNewton, EquilibriumMethod::kIpopt}) {
    auto solver = EquilibriumSolver::create(*scene.energy, *scene.attachments, options_for(method));
    ASSERT_TRUE(solver.has_value());
    Eigen::VectorXd x = scene.energy->rest_dofs();
    ASSERT_TRUE(solver->solve(s, x).converged());
    const Eigen::VectorXd solution = x;
    const EquilibriumSummary again = solver->solve(s, x);
    EXPECT_EQ(again.status, EquilibriumStatus::kConverged) << again.full_report();
    EXPECT_LE(again.iterations, 1) << to_string(method);
    EXPECT_LT((x - solution).norm(), 1e-9 * solution.norm());

    // A nearby plastic state (the Gauss–Newton line search's x(η)) from the old solution.
    Eigen::VectorXd s_near = s;
    for (Eigen::Index t = 0; t < scene.energy->num_tets(); ++t) s_near[6 * t] = 1.02;
    const EquilibriumSummary near = solver->solve(s_near, x);
    EXPECT_EQ(near.status, EquilibriumStatus::kConverged) << near.full_report();
    EXPECT_LE(near.iterations, 10);
  }
}

TEST(Equilibrium, BadInputsAreStatuses) {
  Scene scene = stretched_rotated_scene();
  const Eigen::VectorXd s = identity_plastic_strains(scene.energy->num_tets());
  auto solver = EquilibriumSolver::create(*scene.energy, *scene.attachments);
  ASSERT_TRUE(solver.has_value());

  Eigen::VectorXd short_x = Eigen::VectorXd::Zero(scene.energy->num_dofs() - 3);
  EXPECT_EQ(solver->solve(s, short_x).status, EquilibriumStatus::kInvalidInput);
  Eigen::VectorXd x = scene.energy->rest_dofs();
  EXPECT_EQ(solver->solve(s.head(s.size() - 6), x).status, EquilibriumStatus::kInvalidInput);

  Eigen::VectorXd nan_x = x;
  nan_x[4] = std::numeric_limits<double>::quiet_NaN();
  const EquilibriumSummary bad_x = solver->solve(s, nan_x);
  EXPECT_EQ(bad_x.status, EquilibriumStatus::kNonFinite);
  EXPECT_FALSE(bad_x.residual_norm.has_value());
  EXPECT_TRUE(std::isnan(nan_x[4]));  // unchanged

  Eigen::VectorXd nan_s = s;
  nan_s[7] = std::numeric_limits<double>::infinity();
  EXPECT_EQ(solver->solve(nan_s, x).status, EquilibriumStatus::kNonFinite);
  EXPECT_EQ(x, scene.energy->rest_dofs());

  // A singular plastic strain cannot be evaluated: kNonFinite, not a crash.
  Eigen::VectorXd singular = s;
  singular.segment<6>(0).setZero();
  EXPECT_EQ(solver->solve(singular, x).status, EquilibriumStatus::kNonFinite);

  // Invalid options name the field; mismatched sizes are refused.
  EquilibriumOptions o;
  o.force_tolerance = 0.0;
  std::string error;
  EXPECT_FALSE(EquilibriumSolver::create(*scene.energy, *scene.attachments, o, &error));
  EXPECT_NE(error.find("force_tolerance"), std::string::npos) << error;
  o = {};
  o.backtracking_factor = 1.0;
  EXPECT_NE(o.validate().value_or("").find("backtracking_factor"), std::string::npos);
  o = {};
  o.projection = common::HessianProjection::kNone;
  EXPECT_NE(o.validate().value_or("").find("projection"), std::string::npos);

  Scene other =
      make_scene(1, 1, 1, 0.1, 1.0,
                 [](int, const Eigen::Vector3d& X) -> std::optional<Eigen::Vector3d> { return X; });
  EXPECT_FALSE(EquilibriumSolver::create(*scene.energy, *other.attachments, {}, &error));
  EXPECT_NE(error.find("dofs"), std::string::npos) << error;
}

TEST(Equilibrium, NewtonWithoutProjectionReportsAnIndefiniteStiffness) {
  // Unattached (no springs) body: K_total = K is singular (rigid modes); far from rest the exact
  // K is indefinite. Either way the factorisation must fail as a status, never as a crash.
  Scene scene = make_scene(
      1, 1, 1, 0.1, 1.0,
      [](int, const Eigen::Vector3d&) -> std::optional<Eigen::Vector3d> { return std::nullopt; });
  EquilibriumOptions o;
  o.stiffness_projection = StiffnessProjection::kNever;
  auto solver = EquilibriumSolver::create(*scene.energy, *scene.attachments, o);
  ASSERT_TRUE(solver.has_value());
  Eigen::VectorXd s(scene.energy->num_plastic_dofs());
  for (Eigen::Index t = 0; t < scene.energy->num_tets(); ++t) {
    s.segment<6>(6 * t) = scaled_identity_plastic_strain(1.5);
  }
  Eigen::VectorXd x = scene.energy->rest_dofs();
  const EquilibriumSummary summary = solver->solve(s, x);
  EXPECT_EQ(summary.status, EquilibriumStatus::kNotPositiveDefinite) << summary.full_report();
}

TEST(Equilibrium, IpoptDerivativeCheckerFindsNoErrors) {
  Scene scene = make_scene(2, 1, 1, 0.1, 50.0,
                           [](int v, const Eigen::Vector3d& X) -> std::optional<Eigen::Vector3d> {
                             if (v % 3 == 0) return X + Eigen::Vector3d(0.01, -0.02, 0.015);
                             return std::nullopt;
                           });
  std::mt19937 gen(42);
  Eigen::VectorXd s(scene.energy->num_plastic_dofs());
  for (Eigen::Index t = 0; t < scene.energy->num_tets(); ++t) {
    s.segment<6>(6 * t) = plastic_strain_vector(
        Eigen::Matrix3d::Identity() + 0.1 * testing::random_vector(9, 1.0, gen).reshaped(3, 3));
  }
  Eigen::VectorXd x =
      scene.energy->rest_dofs() + testing::random_vector(scene.energy->num_dofs(), 0.01, gen);

  EquilibriumOptions o;
  o.method = EquilibriumMethod::kIpopt;
  o.ipopt_derivative_test = IpoptDerivativeTest::kSecondOrder;
  o.max_iterations = 0;  // the checker runs before the first iteration
  auto solver = EquilibriumSolver::create(*scene.energy, *scene.attachments, o);
  ASSERT_TRUE(solver.has_value());
  const EquilibriumSummary summary = solver->solve(s, x);
  ASSERT_TRUE(summary.derivative_test_errors.has_value()) << summary.full_report();
  EXPECT_EQ(*summary.derivative_test_errors, 0) << summary.full_report();
}

}  // namespace
}  // namespace sinew::offline
