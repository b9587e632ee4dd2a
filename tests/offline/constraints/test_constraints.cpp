// Tests of offline/constraints: embedding template points in tets (inside, slightly outside, too
// far), the A_k, b_k, c_k of seed 003 appendix F (A_k x is the embedded point's position), and
// the constraint energy ½Σc_k‖A_k x + b_k‖² with its gradient and Hessian against finite
// differences.

#include "offline/constraints/constraints.hpp"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <limits>
#include <vector>

#include "tests/support/finite_difference.hpp"
#include "tests/support/tet_mesh_fixtures.hpp"

namespace {

using sinew::offline::ConstraintKind;
using sinew::offline::ConstraintStatus;
using sinew::offline::EmbeddingStatus;
using sinew::offline::OutsidePointPolicy;
using sinew::offline::PointConstraint;
using sinew::offline::PointConstraints;
using sinew::offline::TetPointLocator;
using sinew::testing::derivatives_match;

// The unit cube [0, 1]³ as 2x2x2 cubes of 6 tets.
sinew::testing::TetMesh unit_cube() {
  return sinew::testing::make_box_mesh(2, 2, 2, 0.5);
}

TEST(TetPointLocator, PointsInsideGetTheirContainingTet) {
  auto& gen = sinew::testing::rng();
  const auto mesh = unit_cube();
  const auto locator = TetPointLocator::create(mesh.rest_positions, mesh.tets);
  ASSERT_TRUE(locator);
  const Eigen::VectorXd X = sinew::common::to_dof_vector(mesh.rest_positions);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 50; ++i) {
    points.push_back(Eigen::Vector3d::Constant(0.5) + sinew::testing::random_vector(3, 0.5, gen));
  }
  points.push_back({0.5, 0.5, 0.5});   // a vertex shared by many tets
  points.push_back({1.0, 0.25, 0.7});  // on the boundary
  points.push_back({0.0, 0.0, 0.0});   // a corner
  for (const Eigen::Vector3d& p : points) {
    const auto embedding = locator->locate(p);
    ASSERT_EQ(embedding.status, EmbeddingStatus::kInside) << p.transpose();
    EXPECT_EQ(embedding.distance, 0.0);
    EXPECT_GE(embedding.point.weights.minCoeff(), -1e-10);
    EXPECT_NEAR(embedding.point.weights.sum(), 1.0, 1e-14);
    EXPECT_LT((sinew::offline::embedded_position(mesh.tets, embedding.point, X) - p).norm(), 1e-14);
  }
}

TEST(TetPointLocator, PointsOutsideUseTheNearestTet) {
  const auto mesh = unit_cube();
  const Eigen::VectorXd X = sinew::common::to_dof_vector(mesh.rest_positions);
  const auto extrapolate = TetPointLocator::create(mesh.rest_positions, mesh.tets);
  sinew::offline::TetPointLocatorOptions options;
  options.outside_policy = OutsidePointPolicy::kProjectToMesh;
  const auto project = TetPointLocator::create(mesh.rest_positions, mesh.tets, options);
  ASSERT_TRUE(extrapolate && project);

  struct Case {
    Eigen::Vector3d point;
    Eigen::Vector3d closest;  // on the cube
  };
  const std::vector<Case> cases = {
      {{1.02, 0.3, 0.4}, {1.0, 0.3, 0.4}},       // off a face
      {{0.7, -0.03, 1.04}, {0.7, 0.0, 1.0}},     // off an edge
      {{-0.01, -0.02, -0.02}, {0.0, 0.0, 0.0}},  // off a corner
  };
  for (const auto& [p, closest] : cases) {
    SCOPED_TRACE(p.transpose());
    const auto e = extrapolate->locate(p);
    ASSERT_EQ(e.status, EmbeddingStatus::kOutside);
    EXPECT_NEAR(e.distance, (p - closest).norm(), 1e-14);
    EXPECT_LT(e.point.weights.minCoeff(), 0.0);  // extrapolated
    EXPECT_LT((sinew::offline::embedded_position(mesh.tets, e.point, X) - p).norm(), 1e-14);

    const auto q = project->locate(p);
    ASSERT_EQ(q.status, EmbeddingStatus::kOutside);
    EXPECT_NEAR(q.distance, (p - closest).norm(), 1e-14);
    EXPECT_GE(q.point.weights.minCoeff(), 0.0);
    EXPECT_LT((sinew::offline::embedded_position(mesh.tets, q.point, X) - closest).norm(), 1e-14);
  }

  options = {};
  options.max_outside_distance = 0.05;
  const auto limited = TetPointLocator::create(mesh.rest_positions, mesh.tets, options);
  ASSERT_TRUE(limited);
  EXPECT_EQ(limited->locate({1.02, 0.5, 0.5}).status, EmbeddingStatus::kOutside);
  const auto far = limited->locate({1.2, 0.5, 0.5});
  EXPECT_EQ(far.status, EmbeddingStatus::kTooFar);
  EXPECT_NEAR(far.distance, 0.2, 1e-14);
  EXPECT_EQ(limited->locate({std::nan(""), 0.5, 0.5}).status, EmbeddingStatus::kNonFinite);

  options.max_outside_distance = -1.0;
  sinew::common::TetMeshCheck check;
  EXPECT_FALSE(TetPointLocator::create(mesh.rest_positions, mesh.tets, options, &check));
  EXPECT_EQ(check.status, sinew::common::TetMeshStatus::kInvalidOptions);
  EXPECT_NE(options.validate()->find("max_outside_distance"), std::string::npos);
}

struct ConstraintFixture {
  sinew::testing::TetMesh mesh = unit_cube();
  Eigen::VectorXd X = sinew::common::to_dof_vector(mesh.rest_positions);
  std::vector<Eigen::Vector3d> material_points;
  std::vector<PointConstraint> constraints;

  explicit ConstraintFixture(std::mt19937& gen) {
    const auto locator = TetPointLocator::create(mesh.rest_positions, mesh.tets);
    const ConstraintKind kinds[3] = {ConstraintKind::kAttachment, ConstraintKind::kLandmark,
                                     ConstraintKind::kIcpMarker};
    for (int k = 0; k < 7; ++k) {
      // Inside points, and one slightly outside (extrapolated weights).
      const Eigen::Vector3d p = k == 6
                                    ? Eigen::Vector3d(1.01, 0.2, 0.6)
                                    : Eigen::Vector3d(Eigen::Vector3d::Constant(0.5) +
                                                      sinew::testing::random_vector(3, 0.45, gen));
      const auto embedding = locator->locate(p);
      EXPECT_TRUE(embedding.ok());
      material_points.push_back(p);
      PointConstraint c;
      c.kind = kinds[k % 3];
      c.point = embedding.point;
      c.target = p + sinew::testing::random_vector(3, 0.3, gen);
      c.weight = 10.0 * (1.0 + k);
      constraints.push_back(c);
    }
  }
};

TEST(PointConstraints, SelectionMatrixReproducesTheEmbeddedPoint) {
  auto& gen = sinew::testing::rng();
  ConstraintFixture f(gen);
  const auto set = PointConstraints::create(f.X.size() / 3, f.mesh.tets, f.constraints);
  ASSERT_TRUE(set);
  ASSERT_EQ(set->size(), 7);
  // Under an affine motion x = A X + t, the material point moves to A p + t (also extrapolated).
  const Eigen::Matrix3d A =
      sinew::testing::random_rotation(gen) * Eigen::Vector3d(1.3, 0.8, 1.1).asDiagonal();
  const Eigen::Vector3d t(0.2, -0.4, 1.0);
  Eigen::VectorXd x(f.X.size());
  for (Eigen::Index v = 0; v < x.size() / 3; ++v)
    x.segment<3>(3 * v) = A * f.X.segment<3>(3 * v) + t;
  const Eigen::MatrixXd stacked = set->stacked_selection();
  ASSERT_EQ(stacked.rows(), 21);
  ASSERT_EQ(stacked.cols(), x.size());
  for (Eigen::Index k = 0; k < set->size(); ++k) {
    const Eigen::Vector3d expected = A * f.material_points[k] + t;
    const Eigen::SparseMatrix<double> A_k = set->selection_matrix(k);
    ASSERT_EQ(A_k.rows(), 3);
    ASSERT_EQ(A_k.cols(), x.size());
    EXPECT_EQ(A_k.nonZeros(), 12);
    EXPECT_LT((A_k * f.X - f.material_points[k]).norm(), 1e-14);
    EXPECT_LT((A_k * x - expected).norm(), 1e-13);
    EXPECT_LT((set->position(k, x) - expected).norm(), 1e-13);
    EXPECT_LT((sinew::offline::embedded_position(f.mesh.tets, f.constraints[k].point, x) - expected)
                  .norm(),
              1e-13);
    EXPECT_EQ(Eigen::MatrixXd(A_k), stacked.middleRows(3 * k, 3));
    EXPECT_EQ(set->offset(k), -f.constraints[k].target);
    EXPECT_LT((set->residual(k, x) - (A_k * x + set->offset(k))).norm(), 1e-13);
  }
}

// Appendix F, literally: ½Σ c_k‖A_k x + b_k‖², Σ c_k A_kᵀ(A_k x + b_k), Σ c_k A_kᵀA_k, from the
// set's own A_k (selection_matrix) and b_k (offset).
struct AppendixFSums {
  double energy = 0.0;
  Eigen::VectorXd gradient;
  Eigen::MatrixXd hessian;
};

AppendixFSums appendix_f_sums(const PointConstraints& set, const Eigen::VectorXd& x) {
  AppendixFSums sums;
  sums.gradient = Eigen::VectorXd::Zero(x.size());
  sums.hessian = Eigen::MatrixXd::Zero(x.size(), x.size());
  for (Eigen::Index k = 0; k < set.size(); ++k) {
    const Eigen::MatrixXd A_k = set.selection_matrix(k);
    const Eigen::Vector3d r = A_k * x + set.offset(k);
    sums.energy += 0.5 * set.weight(k) * r.squaredNorm();
    sums.gradient += set.weight(k) * A_k.transpose() * r;
    sums.hessian += set.weight(k) * A_k.transpose() * A_k;
  }
  return sums;
}

// energy(), gradient() and hessian() equal the literal sums.
void expect_matches_sums(const PointConstraints& set, const Eigen::VectorXd& x,
                         const AppendixFSums& sums) {
  EXPECT_NEAR(set.energy(x), sums.energy, 1e-13 * sums.energy);
  Eigen::VectorXd g(x.size());
  set.gradient(x, g);
  EXPECT_LT((g - sums.gradient).norm(), 1e-13 * sums.gradient.norm());
  EXPECT_LT((Eigen::MatrixXd(set.hessian()) - sums.hessian).norm(), 1e-13 * sums.hessian.norm());
}

// gradient() and hessian() match finite differences of energy() and gradient().
void expect_derivatives_match_fd(const PointConstraints& set, const Eigen::VectorXd& x) {
  const auto E = [&](const Eigen::VectorXd& y) { return set.energy(y); };
  const auto G = [&](const Eigen::VectorXd& y) -> Eigen::VectorXd {
    Eigen::VectorXd out(y.size());
    set.gradient(y, out);
    return out;
  };
  EXPECT_TRUE(derivatives_match(G(x), sinew::testing::fd_gradient(E, x, 1e-5), 1e-8));
  EXPECT_TRUE(derivatives_match(Eigen::MatrixXd(set.hessian()),
                                sinew::testing::fd_jacobian(G, x, 1e-5), 1e-8));
}

TEST(PointConstraints, EnergyGradientHessianMatchDefinitionAndFiniteDifferences) {
  auto& gen = sinew::testing::rng();
  ConstraintFixture f(gen);
  auto set = PointConstraints::create(f.X.size() / 3, f.mesh.tets, f.constraints);
  ASSERT_TRUE(set);
  const Eigen::VectorXd x = f.X + sinew::testing::random_vector(f.X.size(), 0.2, gen);

  const AppendixFSums sums = appendix_f_sums(*set, x);
  ASSERT_GT(sums.energy, 0.1);
  expect_matches_sums(*set, x, sums);
  expect_derivatives_match_fd(*set, x);

  // Upper storage holds the same matrix.
  auto upper = PointConstraints::create(f.X.size() / 3, f.mesh.tets, f.constraints,
                                        sinew::common::PatternStorage::kUpper);
  ASSERT_TRUE(upper);
  const Eigen::MatrixXd H_upper = Eigen::MatrixXd(upper->hessian()).selfadjointView<Eigen::Upper>();
  EXPECT_LT((H_upper - sums.hessian).norm(), 1e-13 * sums.hessian.norm());

  // Re-targeting and re-weighting keep everything consistent (ICP iterations, stages).
  ASSERT_EQ(set->set_target(2, Eigen::Vector3d(0.1, 0.2, 0.3)), ConstraintStatus::kOk);
  ASSERT_EQ(set->set_weight(4, 0.0), ConstraintStatus::kOk);
  ASSERT_EQ(set->set_weight(5, 1234.0), ConstraintStatus::kOk);
  expect_derivatives_match_fd(*set, x);
  EXPECT_EQ(set->set_weight(7, 1.0), ConstraintStatus::kIndexOutOfRange);
  EXPECT_EQ(set->set_weight(0, -1.0), ConstraintStatus::kInvalidWeight);
  EXPECT_EQ(set->set_target(0, Eigen::Vector3d::Constant(std::nan(""))),
            ConstraintStatus::kNonFiniteTarget);
}

// Point to plane (PointConstraint::plane_normal): only the offset along n counts. The literal
// appendix-F sums with A_k = n·nᵀ·[w_a I₃]·S^k and b_k = −n·nᵀ·y_k give the energy, gradient and
// Hessian, finite differences agree, and sliding the point within the plane costs nothing.
TEST(PointConstraints, PlaneNormalsCountOnlyTheOffsetAlongTheNormal) {
  auto& gen = sinew::testing::rng();
  ConstraintFixture f(gen);
  for (std::size_t k = 0; k < f.constraints.size(); k += 2) {
    f.constraints[k].plane_normal = sinew::testing::random_vector(3, 1.0, gen).normalized();
  }
  auto set = PointConstraints::create(f.X.size() / 3, f.mesh.tets, f.constraints);
  ASSERT_TRUE(set);
  const Eigen::VectorXd x = f.X + sinew::testing::random_vector(f.X.size(), 0.2, gen);
  for (Eigen::Index k = 0; k < set->size(); k += 2) {
    const PointConstraint& c = f.constraints[static_cast<std::size_t>(k)];
    const Eigen::MatrixXd A_k = set->selection_matrix(k);
    const Eigen::Vector3d r = A_k * x + set->offset(k);
    const Eigen::Vector3d& n = c.plane_normal;
    // The offset along n, and nothing across it.
    const Eigen::Vector3d full = set->position(k, x) - c.target;
    EXPECT_LT((r - n * n.dot(full)).norm(), 1e-13);
    EXPECT_LT((A_k - n * n.transpose() * A_k).norm(), 1e-13);
  }
  expect_matches_sums(*set, x, appendix_f_sums(*set, x));
  expect_derivatives_match_fd(*set, x);

  // A single point-to-plane constraint: moving the whole mesh within its plane leaves the energy
  // unchanged; moving it along the normal does not.
  PointConstraint one = f.constraints[0];
  auto single = PointConstraints::create(f.X.size() / 3, f.mesh.tets, {one});
  ASSERT_TRUE(single);
  const Eigen::Vector3d n = one.plane_normal;
  const Eigen::Vector3d along_plane = n.unitOrthogonal();
  Eigen::VectorXd slid = x, lifted = x;
  for (Eigen::Index v = 0; v < x.size() / 3; ++v) {
    slid.segment<3>(3 * v) += 0.3 * along_plane;
    lifted.segment<3>(3 * v) += 0.3 * n;
  }
  EXPECT_NEAR(single->energy(slid), single->energy(x), 1e-12);
  EXPECT_GT(std::abs(single->energy(lifted) - single->energy(x)), 1e-3);
}

TEST(PointConstraints, InvalidConstraintsAreReported) {
  auto& gen = sinew::testing::rng();
  ConstraintFixture f(gen);
  const Eigen::Index n = f.X.size() / 3;
  const auto expect_failure = [&](std::vector<PointConstraint> constraints, ConstraintStatus status,
                                  Eigen::Index index) {
    sinew::offline::ConstraintCheck check;
    EXPECT_FALSE(PointConstraints::create(n, f.mesh.tets, std::move(constraints),
                                          sinew::common::PatternStorage::kFull, &check));
    EXPECT_EQ(check.status, status) << check.message();
    ASSERT_TRUE(check.constraint);
    EXPECT_EQ(*check.constraint, index);
  };
  auto c = f.constraints;
  c[3].point.tet = f.mesh.tets.rows();
  expect_failure(c, ConstraintStatus::kTetOutOfRange, 3);
  c = f.constraints;
  c[1].point.weights[0] += 0.1;
  expect_failure(c, ConstraintStatus::kInvalidBarycentric, 1);
  c = f.constraints;
  c[5].weight = -2.0;
  expect_failure(c, ConstraintStatus::kInvalidWeight, 5);
  c = f.constraints;
  c[6].target[2] = std::numeric_limits<double>::infinity();
  expect_failure(c, ConstraintStatus::kNonFiniteTarget, 6);
  c = f.constraints;
  c[2].plane_normal = Eigen::Vector3d(0.0, 0.5, 0.0);
  expect_failure(c, ConstraintStatus::kInvalidNormal, 2);

  sinew::offline::ConstraintCheck check;
  EXPECT_FALSE(PointConstraints::create(n - 1, f.mesh.tets, f.constraints,
                                        sinew::common::PatternStorage::kFull, &check));
  EXPECT_EQ(check.status, ConstraintStatus::kInvalidMesh);

  const auto empty = PointConstraints::create(n, f.mesh.tets, {});
  ASSERT_TRUE(empty);
  EXPECT_EQ(empty->energy(f.X), 0.0);
  EXPECT_EQ(empty->hessian().nonZeros(), 0);
}

}  // namespace
