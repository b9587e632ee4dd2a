// Tests of offline/rigid_motion and offline/rigid_stabilisation (seed 003 §3.6): the Nullspace
// Lemma's six vectors annihilate the tangent stiffness at a free equilibrium (and not away from
// it); the free Newton equilibrium (pinned dofs) converges and is an equilibrium in every row; the
// centroid and polar-rotation constraints (eqs. 19–20) have Jacobians and Hessians that match
// central finite differences; move_to satisfies them exactly without changing the energy; the
// rigid fit recovers a known rotation and translation and refuses collinear points.

#include "offline/rigid/rigid_stabilisation.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

#include "offline/equilibrium/equilibrium.hpp"
#include "offline/plastic/plastic_elastic_energy.hpp"
#include "offline/plastic/plastic_strain.hpp"
#include "offline/rigid/rigid_motion.hpp"
#include "tests/support/offline_fixtures.hpp"
#include "tests/support/tet_mesh_fixtures.hpp"

namespace sinew::offline {
namespace {

using testing::soft_tissue;

Eigen::Matrix3d rotation(double degrees, Eigen::Vector3d axis) {
  return Eigen::AngleAxisd(degrees * EIGEN_PI / 180.0, axis.normalized()).toRotationMatrix();
}

using testing::FreeBlock;

Eigen::VectorXd free_equilibrium(FreeBlock& block) {
  auto none = PointConstraints::create(block.mesh.rest_positions.rows(), block.mesh.tets, {});
  EXPECT_TRUE(none.has_value());
  std::string error;
  auto solver = EquilibriumSolver::create(*block.energy, *none, {}, &error);
  EXPECT_TRUE(solver.has_value()) << error;
  Eigen::VectorXd x = block.energy->rest_dofs();
  const EquilibriumSummary summary = solver->solve(block.s, x);
  EXPECT_TRUE(summary.converged()) << summary.full_report();
  return x;
}

TEST(FreeEquilibrium, PinnedNewtonConvergesInEveryRowAndRigidVectorsSpanTheNullspace) {
  FreeBlock block;
  const Eigen::VectorXd x = free_equilibrium(block);
  PlasticEnergyRequest request = PlasticEnergyRequest::all();
  request.force_jacobian = false;
  ASSERT_TRUE(block.energy->evaluate(block.s, x, request).valid());
  // Every row of f_e vanishes, the pinned ones included.
  const double force_scale = soft_tissue().mu() * 0.05 * 0.05;
  EXPECT_LT(block.energy->gradient_x().lpNorm<Eigen::Infinity>(), 1e-7 * force_scale);
  // The shape really changed (the plastic field is not a rigid motion).
  EXPECT_GT((x - block.energy->rest_dofs()).lpNorm<Eigen::Infinity>(), 0.01);
  // Nullspace Lemma: K ψ = 0 for the six rigid vectors at the equilibrium ...
  const Eigen::SparseMatrix<double> K = block.energy->stiffness();
  const auto psi = rigid_motion_basis(x, false);
  const double k_scale = K.diagonal().cwiseAbs().maxCoeff();
  for (int i = 0; i < 6; ++i) {
    const Eigen::VectorXd Kpsi = K * psi.col(i);
    EXPECT_LT(Kpsi.norm() / (psi.col(i).norm() * k_scale), 1e-7) << "psi " << i;
  }
  // ... and the rotations are NOT in the nullspace away from equilibrium (the rest shape under
  // this plastic field is strained): the lemma needs equilibrium.
  ASSERT_TRUE(block.energy->evaluate(block.s, block.energy->rest_dofs(), request).valid());
  const auto psi0 = rigid_motion_basis(block.energy->rest_dofs(), false);
  const Eigen::VectorXd Kpsi_rot = block.energy->stiffness() * psi0.col(3);
  EXPECT_GT(Kpsi_rot.norm() / (psi0.col(3).norm() * k_scale), 1e-3);
}

std::vector<EmbeddedPoint> some_points(const common::TetIndices& tets, int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<Eigen::Index> tet(0, tets.rows() - 1);
  std::uniform_real_distribution<double> u(0.05, 1.0);
  std::vector<EmbeddedPoint> points;
  for (int k = 0; k < count; ++k) {
    EmbeddedPoint p;
    p.tet = tet(rng);
    p.weights = Eigen::Vector4d(u(rng), u(rng), u(rng), u(rng));
    p.weights /= p.weights.sum();
    points.push_back(p);
  }
  return points;
}

TEST(RigidStabilisation, JacobianAndHessianMatchFiniteDifferences) {
  FreeBlock block;
  const auto points = some_points(block.mesh.tets, 9, 7);
  std::string error;
  auto stabilisation =
      RigidStabilisation::create(block.mesh.tets, block.energy->rest_dofs(), points, &error);
  ASSERT_TRUE(stabilisation.has_value()) << error;
  // A rotated, translated and deformed configuration, and a target frame near it.
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.01);
  Eigen::VectorXd x = block.energy->rest_dofs();
  RigidTransform{rotation(100.0, {1, 2, 3}), {0.3, -0.2, 0.1}}.apply_to_dofs(x);
  for (Eigen::Index i = 0; i < x.size(); ++i) x[i] += noise(rng);
  RigidFrame target = *stabilisation->frame(x);
  target.R = rotation(5.0, {0, 1, 1}) * target.R;
  target.t += Eigen::Vector3d(0.01, 0.02, -0.01);

  StabilisationJacobian G;
  ASSERT_TRUE(stabilisation->jacobian(x, target, G));
  const double h = 1e-6;
  double worst = 0.0;
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    Eigen::VectorXd plus = x, minus = x;
    plus[i] += h;
    minus[i] -= h;
    const Vector6d fd =
        (*stabilisation->residual(plus, target) - *stabilisation->residual(minus, target)) /
        (2 * h);
    worst = std::max(worst, (fd - G.col(i)).lpNorm<Eigen::Infinity>());
  }
  EXPECT_LT(worst, 1e-7 * G.lpNorm<Eigen::Infinity>());
  EXPECT_GT(G.bottomRows<3>().lpNorm<Eigen::Infinity>(), 0.1);  // the rotation rows are not empty

  // Hessian of λᵀg against differences of λᵀG over the support dofs.
  const Vector6d lambda = (Vector6d() << 0.3, -0.7, 0.2, 1.1, -0.4, 0.9).finished();
  Eigen::MatrixXd H;
  ASSERT_TRUE(stabilisation->hessian(x, target, lambda, H));
  const auto& support = stabilisation->support_vertices();
  ASSERT_EQ(H.rows(), 3 * static_cast<Eigen::Index>(support.size()));
  double worst_h = 0.0;
  for (std::size_t v = 0; v < support.size(); ++v) {
    for (int c = 0; c < 3; ++c) {
      Eigen::VectorXd plus = x, minus = x;
      plus[3 * support[v] + c] += h;
      minus[3 * support[v] + c] -= h;
      StabilisationJacobian Gp, Gm;
      ASSERT_TRUE(stabilisation->jacobian(plus, target, Gp));
      ASSERT_TRUE(stabilisation->jacobian(minus, target, Gm));
      const Eigen::VectorXd fd = (Gp - Gm).transpose() * lambda / (2 * h);
      for (std::size_t u = 0; u < support.size(); ++u) {
        const Eigen::Vector3d column =
            H.block<3, 1>(3 * static_cast<Eigen::Index>(u), 3 * static_cast<Eigen::Index>(v) + c);
        worst_h =
            std::max(worst_h, (fd.segment<3>(3 * support[u]) - column).lpNorm<Eigen::Infinity>());
      }
    }
  }
  EXPECT_GT(H.lpNorm<Eigen::Infinity>(), 0.1);
  EXPECT_LT(worst_h, 1e-6 * H.lpNorm<Eigen::Infinity>());
  EXPECT_LT((H - H.transpose()).lpNorm<Eigen::Infinity>(), 1e-9 * H.lpNorm<Eigen::Infinity>());
}

TEST(RigidStabilisation, MoveToSatisfiesEquations19And20WithoutChangingTheEnergy) {
  FreeBlock block;
  const Eigen::VectorXd x0 = free_equilibrium(block);
  auto stabilisation = RigidStabilisation::create(block.mesh.tets, block.energy->rest_dofs(),
                                                  some_points(block.mesh.tets, 12, 11));
  ASSERT_TRUE(stabilisation.has_value());
  const RigidFrame target{rotation(170.0, {-1, 0.5, 2}), {0.3, 0.0, -0.3}};
  Eigen::VectorXd x = x0;
  ASSERT_TRUE(stabilisation->move_to(target, x));
  EXPECT_LT(stabilisation->residual(x, target)->lpNorm<Eigen::Infinity>(), 1e-12);
  const RigidFrame reached = *stabilisation->frame(x);
  EXPECT_LT((reached.R - target.R).norm(), 1e-12);
  EXPECT_LT((reached.t - target.t).norm(), 1e-12);
  auto energy_at = [&](const Eigen::VectorXd& at) {
    EXPECT_TRUE(block.energy->evaluate(block.s, at, PlasticEnergyRequest{}).valid());
    return block.energy->energy();
  };
  const double e0 = energy_at(x0);
  const double e1 = energy_at(x);
  EXPECT_NEAR(e1, e0, 1e-10 * std::abs(e0));
  EXPECT_GT(std::abs(e0), 0.0);
}

TEST(RigidMotion, FitRecoversAKnownTransformAndRefusesCollinearPoints) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const RigidTransform truth{rotation(120.0, {1, -1, 0.5}), {0.3, 0.1, -0.2}};
  std::vector<Eigen::Vector3d> from, to;
  for (int k = 0; k < 10; ++k) {
    from.emplace_back(u(rng), u(rng), u(rng));
    to.push_back(truth.apply(from.back()));
  }
  const auto fit = fit_rigid_transform(from, to);
  ASSERT_TRUE(fit.has_value());
  EXPECT_LT((fit->rotation - truth.rotation).norm(), 1e-12);
  EXPECT_LT((fit->translation - truth.translation).norm(), 1e-12);
  EXPECT_NEAR(fit->rotation.determinant(), 1.0, 1e-12);
  // A mirrored target still gives a proper rotation.
  std::vector<Eigen::Vector3d> mirrored;
  for (const auto& p : to) mirrored.emplace_back(-p.x(), p.y(), p.z());
  EXPECT_NEAR(fit_rigid_transform(from, mirrored)->rotation.determinant(), 1.0, 1e-12);
  const std::vector<Eigen::Vector3d> line{{0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {3, 3, 3}};
  EXPECT_FALSE(fit_rigid_transform(line, line).has_value());
  EXPECT_FALSE(fit_rigid_transform(from, std::vector<Eigen::Vector3d>(from.begin(), from.end() - 1))
                   .has_value());
}

}  // namespace
}  // namespace sinew::offline
