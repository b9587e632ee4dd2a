// Tests of the free-object ("un-attached") registration of seed 003 §3.6 (offline/gauss_newton,
// register_free and free_constraint_jacobian):
// (a) the Gauss–Newton rows Z for a free object predict how the marker residuals change with s
//     when every equilibrium is re-solved and moved to the same rigid frame (eqs. 18–20): the
//     Singular Lemma (ii) solve plus the rigid correction are the exact derivative (central
//     differences);
// (b) ground truth: a free bar with a known smooth anisotropic plastic field, its equilibrium
//     moved far away (120° about an oblique axis, 3 lengths away) is the "scan"; surface vertices
//     as landmarks; the registration recovers the surface;
// (c) the same case with the scan rotated by 0°, 90° and 180° converges to the same shape up to
//     the rigid motion: register_free works with the scan moved onto the template, so the three
//     runs do the same arithmetic (2e-16 m apart; 6e-10 m when each ran in its scan's frame).

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>
#include <set>

#include "offline/equilibrium/equilibrium.hpp"
#include "offline/plastic/plastic_elastic_energy.hpp"
#include "offline/plastic/plastic_strain.hpp"
#include "offline/registration/gauss_newton.hpp"
#include "offline/rigid/rigid_motion.hpp"
#include "offline/rigid/rigid_stabilisation.hpp"
#include "tests/support/offline_fixtures.hpp"
#include "tests/support/tet_mesh_fixtures.hpp"

namespace sinew::offline {
namespace {

using testing::at_vertex;
using testing::soft_tissue;

constexpr double kLength = 0.2;

// A free bar of nx x n x n cubes of side h (0.2 m long) and a smooth, anisotropic plastic field.
struct FreeBar {
  testing::TetMesh mesh;
  std::optional<PlasticElasticEnergy> energy;
  Eigen::VectorXd true_s;
  Eigen::VectorXd true_x;  // its equilibrium near the template (centred like it)
  std::vector<int> surface;
};

FreeBar make_free_bar(int nx = 8, int n = 3) {
  FreeBar bar;
  const double h = kLength / nx;
  bar.mesh = testing::make_box_mesh(nx, n, n, h);
  bar.energy = PlasticElasticEnergy::create(bar.mesh.rest_positions, bar.mesh.tets, soft_tissue());
  const Eigen::Index m = bar.mesh.tets.rows();
  bar.true_s.resize(6 * m);
  for (Eigen::Index t = 0; t < m; ++t) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (int a = 0; a < 4; ++a)
      c += bar.mesh.rest_positions.row(bar.mesh.tets(t, a)).transpose() / 4;
    const double u = c.x() / kLength;
    Eigen::Matrix3d Fp = Eigen::Matrix3d::Identity();
    Fp(0, 0) += 0.3 * u;
    Fp(1, 1) += 0.25 * std::sin(EIGEN_PI * u);
    Fp(0, 2) = Fp(2, 0) = 0.08 * u;
    bar.true_s.segment<6>(6 * t) = plastic_strain_vector(Fp);
  }
  auto none = PointConstraints::create(bar.mesh.rest_positions.rows(), bar.mesh.tets, {});
  auto solver = EquilibriumSolver::create(*bar.energy, *none);
  EXPECT_TRUE(solver.has_value());
  bar.true_x = bar.energy->rest_dofs();
  EXPECT_TRUE(solver->solve(bar.true_s, bar.true_x).converged());
  const Eigen::Vector3d lo = bar.mesh.rest_positions.colwise().minCoeff();
  const Eigen::Vector3d hi = bar.mesh.rest_positions.colwise().maxCoeff();
  for (int v = 0; v < bar.mesh.rest_positions.rows(); ++v) {
    const Eigen::Vector3d X = bar.mesh.rest_positions.row(v).transpose();
    if (((X - lo).array().abs() < 1e-9).any() || ((X - hi).array().abs() < 1e-9).any()) {
      bar.surface.push_back(v);
    }
  }
  return bar;
}

Eigen::Matrix3d rotation(double degrees, const Eigen::Vector3d& axis) {
  return Eigen::AngleAxisd(degrees * EIGEN_PI / 180.0, axis.normalized()).toRotationMatrix();
}

// Largest distance between corresponding surface vertices of a and b after the best rigid
// alignment of a onto b (over all vertices): shape difference up to rigid motion.
double shape_difference(const FreeBar& bar, const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  std::vector<Eigen::Vector3d> from, to;
  for (Eigen::Index v = 0; v < a.size() / 3; ++v) {
    from.push_back(a.segment<3>(3 * v));
    to.push_back(b.segment<3>(3 * v));
  }
  const auto fit = fit_rigid_transform(from, to);
  double worst = 0.0;
  for (int v : bar.surface) worst = std::max(worst, (fit->apply(from[v]) - to[v]).norm());
  return worst;
}

TEST(FreeConstraintJacobian, PredictsTheResidualChangeOfStabilisedEquilibria) {
  FreeBar bar = make_free_bar(4, 2);
  // Landmarks at a few surface vertices, targets somewhere nearby.
  std::vector<PointConstraint> list;
  for (std::size_t k = 0; k < bar.surface.size(); k += 5) {
    PointConstraint c;
    c.kind = ConstraintKind::kLandmark;
    c.point = at_vertex(bar.mesh.tets, bar.surface[k]);
    c.target = bar.true_x.segment<3>(3 * bar.surface[k]) + Eigen::Vector3d(0.01, -0.005, 0.002);
    c.weight = 3.0;
    list.push_back(c);
  }
  auto terms = PointConstraints::create(bar.mesh.rest_positions.rows(), bar.mesh.tets, list);
  ASSERT_TRUE(terms.has_value());
  std::vector<EmbeddedPoint> points;
  for (const PointConstraint& c : list) points.push_back(c.point);
  auto stabilisation = RigidStabilisation::create(bar.mesh.tets, bar.energy->rest_dofs(), points);
  ASSERT_TRUE(stabilisation.has_value());
  // The equilibrium of the true field, moved to some frame.
  Eigen::VectorXd x = bar.true_x;
  const RigidFrame frame{rotation(40.0, {1, 1, 0}), {0.1, 0.2, 0.3}};
  ASSERT_TRUE(stabilisation->move_to(frame, x));

  PlasticElasticEnergyOptions exact;
  exact.storage = common::PatternStorage::kFull;
  auto energy =
      PlasticElasticEnergy::create(bar.mesh.rest_positions, bar.mesh.tets, soft_tissue(), exact);
  RigidNullspaceSolver tangent;
  std::string why;
  const auto jacobian = free_constraint_jacobian(*energy, *terms, *stabilisation, frame, bar.true_s,
                                                 x, tangent, &why);
  ASSERT_TRUE(jacobian.has_value()) << why;

  auto none = PointConstraints::create(bar.mesh.rest_positions.rows(), bar.mesh.tets, {});
  EquilibriumOptions tight;
  tight.force_tolerance = 1e-12;
  auto solver = EquilibriumSolver::create(*bar.energy, *none, tight);
  std::mt19937 rng(2);
  std::normal_distribution<double> normal;
  Eigen::VectorXd ds(bar.true_s.size());
  for (Eigen::Index i = 0; i < ds.size(); ++i) ds[i] = normal(rng);
  const double h = 1e-5;
  auto residual_at = [&](double eta) {
    const Eigen::VectorXd s = bar.true_s + eta * ds;
    Eigen::VectorXd xs = x;
    EXPECT_TRUE(solver->solve(s, xs).converged());
    EXPECT_TRUE(stabilisation->move_to(frame, xs));
    Eigen::VectorXd r(3 * terms->size());
    for (Eigen::Index k = 0; k < terms->size(); ++k) {
      r.segment<3>(3 * k) = std::sqrt(terms->weight(k)) * terms->residual(k, xs);
    }
    return r;
  };
  const Eigen::VectorXd fd = (residual_at(h) - residual_at(-h)) / (2 * h);
  const Eigen::VectorXd predicted = jacobian->Zt.transpose() * ds;
  EXPECT_GT(predicted.norm(), 1e-3);
  EXPECT_LT((fd - predicted).norm(), 1e-4 * predicted.norm())
      << "fd " << fd.norm() << " predicted " << predicted.norm();
}

struct FreeRun {
  RegistrationResult result;
  double surface_error = 0.0;  // max over surface vertices vs the moved truth
  double diagonal = 0.0;
};

FreeRun register_moved_bar(const FreeBar& bar, const RigidTransform& motion, int every) {
  // The scan: the true equilibrium moved far away; landmarks at every `every`-th surface vertex.
  Eigen::VectorXd scan = bar.true_x;
  motion.apply_to_dofs(scan);
  RegistrationConstraints constraints;
  for (std::size_t k = 0; k < bar.surface.size(); k += static_cast<std::size_t>(every)) {
    PointConstraint c;
    c.kind = ConstraintKind::kLandmark;
    c.point = at_vertex(bar.mesh.tets, bar.surface[k]);
    c.target = scan.segment<3>(3 * bar.surface[k]);
    constraints.landmarks.push_back(c);
  }
  FreeRun run;
  run.result = register_free(*bar.energy, constraints, nullptr);
  const Eigen::Vector3d lo = bar.mesh.rest_positions.colwise().minCoeff();
  const Eigen::Vector3d hi = bar.mesh.rest_positions.colwise().maxCoeff();
  run.diagonal = (hi - lo).norm();
  for (int v : bar.surface) {
    run.surface_error = std::max(run.surface_error,
                                 (run.result.x.segment<3>(3 * v) - scan.segment<3>(3 * v)).norm());
  }
  return run;
}

TEST(RegisterFree, RecoversAFarMovedFreeBarFromLandmarks) {
  const FreeBar bar = make_free_bar();
  const RigidTransform motion{rotation(120.0, {1, 2, -1}), {0.6, -0.3, 0.2}};
  const FreeRun run = register_moved_bar(bar, motion, 3);
  ASSERT_TRUE(run.result.summary.usable()) << run.result.summary.full_report();
  std::cout << run.result.summary.full_report() << "surface error " << run.surface_error
            << " m = " << 100 * run.surface_error / run.diagonal << "% of the diagonal\n";
  EXPECT_LT(run.surface_error, 0.01 * run.diagonal);
  // The recovered plastic field correlates with the truth.
  const Eigen::VectorXd a =
      run.result.s - run.result.s.mean() * Eigen::VectorXd::Ones(run.result.s.size());
  const Eigen::VectorXd b =
      bar.true_s - bar.true_s.mean() * Eigen::VectorXd::Ones(bar.true_s.size());
  EXPECT_GT(a.dot(b) / (a.norm() * b.norm()), 0.9);
}

TEST(RegisterFree, SameShapeWhateverTheScanRotation) {
  const FreeBar bar = make_free_bar(6, 2);
  std::vector<Eigen::VectorXd> shapes;
  for (double degrees : {0.0, 90.0, 180.0}) {
    const FreeRun run = register_moved_bar(
        bar, RigidTransform{rotation(degrees, {0.3, -1, 0.5}), {0.1, 0.4, 0}}, 2);
    ASSERT_TRUE(run.result.summary.usable()) << degrees << ": " << run.result.summary.full_report();
    std::cout << degrees << " deg: surface error " << run.surface_error << " m, "
              << run.result.summary.brief_report() << "\n";
    EXPECT_LT(run.surface_error, 0.01 * run.diagonal) << degrees;
    shapes.push_back(run.result.x);
  }
  const double diagonal = std::sqrt(kLength * kLength + 2 * (kLength / 3) * (kLength / 3));
  for (std::size_t k = 1; k < shapes.size(); ++k) {
    const double d = shape_difference(bar, shapes[k], shapes[0]);
    std::cout << "shape difference vs 0 deg: " << d << " m\n";
    EXPECT_LT(d, 1e-12 * diagonal) << k;
  }
}

}  // namespace
}  // namespace sinew::offline
