// Tests of offline/gauss_newton: the staged Gauss–Newton registration of seed 003 (§3.4).
// (a) Brent's line minimiser finds the minimum of smooth and kinked 1D functions within its
// tolerance and budget; (b) ground truth in the style of Fig. 21: a bar with one end attached is
// given a known smooth, spatially varying anisotropic plastic field; its equilibrium is the
// "scan"; 30% of the surface vertices become landmarks; the registration recovers the surface to
// 1% of the bounding-box diagonal and a plastic field that correlates with the truth (with 12%
// the error is 3.5%, with 60% 0.22%: the density of markers, not the solver, limits it here);
// (c) invalid options and missing attachments are statuses with messages.

#include "offline/registration/gauss_newton.hpp"

#include <gtest/gtest.h>

#include <optional>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "offline/constraints/constraints.hpp"
#include "offline/equilibrium/equilibrium.hpp"
#include "offline/plastic/plastic_elastic_energy.hpp"
#include "offline/plastic/plastic_strain.hpp"
#include "offline/plastic/plastic_strain_laplacian.hpp"
#include "offline/registration/marker_coverage.hpp"
#include "tests/support/offline_fixtures.hpp"
#include "tests/support/tet_mesh_fixtures.hpp"

namespace sinew::offline {
namespace {

using testing::at_vertex;
using testing::soft_tissue;

// GaussNewtonOptions::inverted_equilibrium_fallback below rescue_min_damping (issue 51): the best
// trial whose only equilibrium inverts a tet is taken only when no trial of the iteration lowered
// Φ, and only when it lowers Φ itself (the bunny twisted 45° went 0.087 → 0.382 mm when an
// inverted μ = 0 step was taken although μ = 100 lowered Φ uninverted).
TEST(LineSearch, ADeferredInvertedTrialIsTakenOnlyWhenNoTrialLoweredPhi) {
  const double before = 10.0;
  // No trial lowered Φ (the best is still η = 0 at Φ before): taken when it lowers Φ.
  EXPECT_TRUE(take_deferred_inverted_trial(0.0, before, 9.0));
  EXPECT_FALSE(take_deferred_inverted_trial(0.0, before, 10.0));
  EXPECT_FALSE(take_deferred_inverted_trial(0.0, before, 11.0));
  // None kept aside (+∞).
  EXPECT_FALSE(take_deferred_inverted_trial(0.0, before, std::numeric_limits<double>::infinity()));
  // An uninverted trial lowered Φ (η > 0): never taken, even when the inverted one is lower.
  EXPECT_FALSE(take_deferred_inverted_trial(0.5, 9.5, 1.0));
  EXPECT_FALSE(take_deferred_inverted_trial(1.0, 9.99, 9.0));
}

TEST(BrentMinimise, FindsSmoothAndKinkedMinima) {
  int calls = 0;
  const BrentResult smooth = brent_minimise(
      [&](double t) {
        ++calls;
        return (t - 0.3) * (t - 0.3) + 1.0;
      },
      0.0, 1.0, 1e-4, 40);
  EXPECT_NEAR(smooth.x, 0.3, 1e-3);
  EXPECT_EQ(smooth.evaluations, calls);
  EXPECT_LE(smooth.evaluations, 40);
  const BrentResult kinked =
      brent_minimise([](double t) { return std::abs(t - 0.71); }, 0.0, 1.0, 1e-4, 60);
  EXPECT_NEAR(kinked.x, 0.71, 1e-3);
  // Infinite values (failed equilibria) are just bad values.
  const BrentResult walled = brent_minimise(
      [](double t) { return t > 0.5 ? INFINITY : (t - 0.45) * (t - 0.45); }, 0.0, 1.0, 1e-4, 60);
  EXPECT_NEAR(walled.x, 0.45, 2e-3);
}

// A bar of nx x n x n cubes of side h (default 8x3x3 of 2.5 cm: 0.2 x 0.075 x 0.075 m), face
// x = 0 attached at rest.
struct Bar {
  testing::TetMesh mesh;
  std::optional<PlasticElasticEnergy> energy;
  std::vector<PointConstraint> attachments;
  double length = 0.2;
};

Bar make_bar(int nx = 8, int n = 3, double h = 0.025) {
  Bar bar;
  bar.mesh = testing::make_box_mesh(nx, n, n, h);
  bar.energy = PlasticElasticEnergy::create(bar.mesh.rest_positions, bar.mesh.tets, soft_tissue());
  for (int v = 0; v < bar.mesh.rest_positions.rows(); ++v) {
    const Eigen::Vector3d X = bar.mesh.rest_positions.row(v).transpose();
    if (X.x() > 1e-9) continue;
    PointConstraint c;
    c.kind = ConstraintKind::kAttachment;
    c.point = at_vertex(bar.mesh.tets, v);
    c.target = X;
    c.weight = 1e4;  // N/m, stiff against μh ≈ 90 N/m
    bar.attachments.push_back(c);
  }
  return bar;
}

// The truth: Fp grows along the bar (up to 1.3x), swells transversally in y with a bump in the
// middle (up to 1.25x), and shears in x-z; symmetric positive definite everywhere. kFlatEnds: the
// same amplitudes with zero slope along the bar at both ends.
enum class TruthShape { kLinear, kFlatEnds };

Eigen::VectorXd true_plastic_field(const Bar& bar, TruthShape shape = TruthShape::kLinear) {
  const Eigen::Index m = bar.mesh.tets.rows();
  Eigen::VectorXd s(6 * m);
  for (Eigen::Index t = 0; t < m; ++t) {
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (int a = 0; a < 4; ++a)
      centroid += bar.mesh.rest_positions.row(bar.mesh.tets(t, a)).transpose() / 4;
    const double u = centroid.x() / bar.length;
    Eigen::Matrix3d Fp = Eigen::Matrix3d::Identity();
    const bool flat = shape == TruthShape::kFlatEnds;
    const double g = flat ? 0.5 * (1.0 - std::cos(EIGEN_PI * u)) : u;
    Fp(0, 0) += 0.3 * g;
    Fp(1, 1) += flat ? 0.125 * (1.0 - std::cos(2.0 * EIGEN_PI * u)) : 0.25 * std::sin(EIGEN_PI * u);
    Fp(0, 2) = Fp(2, 0) = 0.08 * g;
    s.segment<6>(6 * t) = plastic_strain_vector(Fp);
  }
  return s;
}

std::set<int> surface_vertices(const testing::TetMesh& mesh) {
  std::set<int> on_surface;
  const Eigen::Vector3d lo = mesh.rest_positions.colwise().minCoeff();
  const Eigen::Vector3d hi = mesh.rest_positions.colwise().maxCoeff();
  for (int v = 0; v < mesh.rest_positions.rows(); ++v) {
    const Eigen::Vector3d X = mesh.rest_positions.row(v).transpose();
    if (((X - lo).array().abs() < 1e-9).any() || ((X - hi).array().abs() < 1e-9).any()) {
      on_surface.insert(v);
    }
  }
  return on_surface;
}

// The "scan": the equilibrium of the bar under the true plastic field, and the surface vertices
// away from the attached face in a seeded random order (marker candidates).
struct Truth {
  Eigen::VectorXd s;
  Eigen::VectorXd x;
  std::set<int> surface;
  std::vector<int> candidates;
};

Truth make_truth(const Bar& bar, unsigned seed, TruthShape shape = TruthShape::kLinear) {
  Truth truth;
  auto springs =
      PointConstraints::create(bar.mesh.rest_positions.rows(), bar.mesh.tets, bar.attachments);
  EXPECT_TRUE(springs.has_value());
  auto equilibrium = EquilibriumSolver::create(*bar.energy, *springs);
  EXPECT_TRUE(equilibrium.has_value());
  truth.s = true_plastic_field(bar, shape);
  truth.x = bar.energy->rest_dofs();
  EXPECT_TRUE(equilibrium->solve(truth.s, truth.x).converged());
  truth.surface = surface_vertices(bar.mesh);
  for (int v : truth.surface) {
    if (bar.mesh.rest_positions(v, 0) > 1e-9) truth.candidates.push_back(v);
  }
  std::mt19937 rng(seed);
  std::shuffle(truth.candidates.begin(), truth.candidates.end(), rng);
  return truth;
}

TEST(GaussNewton, RecoversAKnownPlasticFieldFromSparseLandmarks) {
  Bar bar = make_bar();
  ASSERT_TRUE(bar.energy.has_value());
  const Truth truth = make_truth(bar, 7);
  const Eigen::VectorXd& s_true = truth.s;
  const Eigen::VectorXd& x_true = truth.x;
  const std::set<int>& surface = truth.surface;
  const std::vector<int>& candidates = truth.candidates;

  // 30% of the surface vertices (away from the attached face) as landmarks.
  const std::size_t count = (surface.size() * 30) / 100;
  RegistrationConstraints constraints;
  constraints.attachments = bar.attachments;
  for (std::size_t i = 0; i < count; ++i) {
    PointConstraint c;
    c.kind = ConstraintKind::kLandmark;
    c.point = at_vertex(bar.mesh.tets, candidates[i]);
    c.target = x_true.segment<3>(3 * candidates[i]);
    constraints.landmarks.push_back(c);
  }

  GaussNewtonOptions options;
  const RegistrationResult result = register_attached(*bar.energy, constraints, nullptr, options);
  ASSERT_TRUE(result.summary.usable()) << result.summary.full_report();
  std::cout << result.summary.full_report();

  const double diagonal =
      (bar.mesh.rest_positions.colwise().maxCoeff() - bar.mesh.rest_positions.colwise().minCoeff())
          .norm();
  double worst = 0.0;
  for (int v : surface) {
    worst = std::max(worst, (result.x.segment<3>(3 * v) - x_true.segment<3>(3 * v)).norm());
  }
  double moved = 0.0;
  for (int v : surface) {
    moved = std::max(moved,
                     (x_true.segment<3>(3 * v) - bar.energy->rest_dofs().segment<3>(3 * v)).norm());
  }
  std::cout << "surface error max " << worst << " m = " << 100 * worst / diagonal
            << "% of the diagonal; truth moved up to " << moved << " m\n";
  EXPECT_LT(worst, 0.01 * diagonal);
  EXPECT_LT(result.summary.marker_error_max, 1e-4);  // landmarks met to 0.1 mm
  EXPECT_GT(moved, 0.1 * diagonal);                  // the truth is a large deformation

  // Correlation of Fp − I entries (recovered vs true) over all tets.
  const Eigen::VectorXd identity = identity_plastic_strains(bar.mesh.tets.rows());
  const Eigen::VectorXd a = result.s - identity, b = s_true - identity;
  const double correlation =
      (a.array() - a.mean()).matrix().dot((b.array() - b.mean()).matrix()) /
      ((a.array() - a.mean()).matrix().norm() * (b.array() - b.mean()).matrix().norm());
  std::cout << "plastic field correlation " << correlation << "\n";
  EXPECT_GT(correlation, 0.95);
}

// Fig. 21 style ground truth on a finer bar (by default 16x4x4 cubes, 1,536 tets): a few percent of
// its surface vertices are given as unlabelled ICP markers (the acceptance case), whose
// correspondence is the closest point on the deformed surface, recomputed every iteration, or as
// landmarks with their correspondence (as the paper ran its Fig. 21).
struct GroundTruthFit {
  double vertex_error = 0.0;   // max over surface vertices of |x − x_true|, fraction of diagonal
  double surface_error = 0.0;  // point to surface, max of both directions, fraction of diagonal
  double surface_mean = 0.0;   // point to surface, mean of both directions, fraction of diagonal
  // surface_error as a fraction of the truth's own (deformed) bounding-box diagonal
  double surface_error_of_truth = 0.0;
  double correlation = 0.0;                        // of the Fp − I entries, recovered vs true
  double marker_error = 0.0;                       // max, fraction of diagonal
  double smoothness = 0.0, true_smoothness = 0.0;  // ½‖L s‖² of the result and of the truth
  // offline/registration/marker_coverage.hpp on the truth's surface: at the worst point-to-surface
  // error's vertex, the distance to the nearest marker or attachment in nominal spacings and the
  // pinning along the normal in units of the threshold; the area fractions uncovered and weakly
  // pinned.
  double worst_error_spacings = 0.0, worst_error_pinning = 0.0;
  double uncovered = 0.0, weakly_pinned = 0.0;
};

// cubes: the bar's cubes along it (cubes / 4 across, same 0.2 x 0.05 x 0.05 m); seed: the draw of
// markers; start_from_truth: the ICP stage starts from (s, x) of the truth instead of the
// template (a checkpoint), to tell a local minimum from a minimum that is itself off.
// landmarks: the same vertices given with their correspondence (landmarks, as the paper's Fig. 21
// ran it) instead of as ICP markers.
struct GroundTruthCase {
  int cubes = 16;
  unsigned seed = 11;
  TruthShape shape = TruthShape::kLinear;
  bool start_from_truth = false;
  bool landmarks = false;
  int percent = 5;  // of the surface vertices given as markers
};

GroundTruthFit register_ground_truth(const GaussNewtonOptions& options,
                                     const GroundTruthCase& setup = {}) {
  Bar bar = make_bar(setup.cubes, setup.cubes / 4, 0.2 / setup.cubes);
  EXPECT_TRUE(bar.energy.has_value());
  const Truth truth = make_truth(bar, setup.seed, setup.shape);
  const std::size_t count = (truth.surface.size() * setup.percent) / 100;
  RegistrationConstraints constraints;
  constraints.attachments = bar.attachments;
  for (std::size_t i = 0; i < count; ++i) {
    const int v = truth.candidates[i];
    if (!setup.landmarks) {
      constraints.icp_markers.push_back(truth.x.segment<3>(3 * v));
      continue;
    }
    PointConstraint c;
    c.kind = ConstraintKind::kLandmark;
    c.point = at_vertex(bar.mesh.tets, v);
    c.target = truth.x.segment<3>(3 * v);
    constraints.landmarks.push_back(c);
  }
  auto query = SurfaceClosestPoint::create(bar.mesh.rest_positions.rows(), bar.mesh.tets);
  EXPECT_TRUE(query.has_value());
  BoundaryClosestPoint closest(*query);
  GaussNewtonCheckpoint truth_start;
  truth_start.next_stage = RegistrationStage::kIcpMarkers;
  truth_start.s = truth.s;
  truth_start.x = truth.x;
  const RegistrationResult result =
      register_attached(*bar.energy, constraints, &closest, options, {}, {},
                        setup.start_from_truth ? &truth_start : nullptr);
  EXPECT_TRUE(result.summary.usable()) << result.summary.full_report();
  std::cout << count << (setup.landmarks ? " landmarks of " : " ICP markers of ")
            << truth.surface.size() << " surface vertices, "
            << options.icp_point_to_plane_iterations << " point-to-plane iterations\n"
            << result.summary.full_report();

  const double diagonal =
      (bar.mesh.rest_positions.colwise().maxCoeff() - bar.mesh.rest_positions.colwise().minCoeff())
          .norm();
  GroundTruthFit m;
  for (int v : truth.surface) {
    m.vertex_error = std::max(m.vertex_error, (result.x - truth.x).segment<3>(3 * v).norm());
  }
  // Point to surface both ways (sampled at the vertices): sliding along the surface is free.
  int worst_vertex = -1;
  const auto one_way = [&](const Eigen::VectorXd& from, const Eigen::VectorXd& to) {
    EXPECT_EQ(query->update(to), SurfaceUpdateStatus::kOk);
    for (int v : truth.surface) {
      const double d = query->query(Eigen::Vector3d(from.segment<3>(3 * v))).distance;
      if (d > m.surface_error) worst_vertex = v;
      m.surface_error = std::max(m.surface_error, d);
      m.surface_mean += d / (2.0 * truth.surface.size());
    }
  };
  one_way(result.x, truth.x);
  one_way(truth.x, result.x);
  const Eigen::VectorXd identity = identity_plastic_strains(bar.mesh.tets.rows());
  const Eigen::VectorXd a = result.s - identity, b = truth.s - identity;
  m.correlation = (a.array() - a.mean()).matrix().dot((b.array() - b.mean()).matrix()) /
                  ((a.array() - a.mean()).matrix().norm() * (b.array() - b.mean()).matrix().norm());
  const PlasticStrainLaplacian laplacian = make_plastic_strain_laplacian(bar.mesh.tets);
  m.smoothness = 0.5 * (laplacian.matrix * result.s).squaredNorm();
  m.true_smoothness = 0.5 * (laplacian.matrix * truth.s).squaredNorm();
  const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>> deformed(
      truth.x.data(), truth.x.size() / 3, 3);
  const double truth_diagonal =
      (deformed.colwise().maxCoeff() - deformed.colwise().minCoeff()).norm();
  m.surface_error_of_truth = m.surface_error / truth_diagonal;
  {
    // The truth's vertices with its boundary triangles: interior vertices are left out.
    auto boundary = BoundarySurface::extract(bar.mesh.rest_positions.rows(), bar.mesh.tets);
    EXPECT_TRUE(boundary.has_value());
    std::vector<Eigen::Vector3d> pinned, sliding;
    for (std::size_t i = 0; i < count; ++i)
      (setup.landmarks ? pinned : sliding).push_back(truth.x.segment<3>(3 * truth.candidates[i]));
    for (const PointConstraint& fixed : bar.attachments) pinned.push_back(fixed.target);
    const MarkerCoverage coverage =
        marker_coverage(deformed, boundary->triangles(), pinned, sliding, count);
    m.worst_error_spacings = coverage.distance[worst_vertex] / coverage.nominal_spacing;
    m.worst_error_pinning = coverage.pinning[worst_vertex] / coverage.pinning_threshold;
    m.uncovered = coverage.uncovered_area_fraction;
    m.weakly_pinned = coverage.weakly_pinned_area_fraction;
  }
  m.marker_error = result.summary.marker_error_max / diagonal;
  m.vertex_error /= diagonal;
  m.surface_error /= diagonal;
  m.surface_mean /= diagonal;
  std::cout << (setup.landmarks ? "Landmark" : "ICP") << " ground truth: vertex error max "
            << 100 * m.vertex_error << "% of the diagonal; point to surface max "
            << 100 * m.surface_error << "%, mean " << 100 * m.surface_mean
            << "%; plastic field correlation " << m.correlation << "; 0.5|Ls|^2 " << m.smoothness
            << " (truth " << m.true_smoothness << ")\n"
            << "point to surface max " << 100 * m.surface_error_of_truth
            << "% of the truth's diagonal (" << truth_diagonal << " m)\n"
            << "marker coverage: the worst error's vertex is " << m.worst_error_spacings
            << " nominal spacings from the nearest marker and pinned along its normal at "
            << m.worst_error_pinning << " x the threshold; " << 100 * m.uncovered
            << "% of the area uncovered, " << 100 * m.weakly_pinned << "% weakly pinned\n";
  return m;
}

// DISABLED: it does not hold yet. The 14 markers (5% of 290 surface vertices) are met to 1 µm,
// and the truth moves by 3.7 cm. The paper's point-to-point ICP stage ends 6.7% of the diagonal
// off at the vertices (5.8% point to surface, 0.96% mean; correlation 0.73): each marker pins the
// material point it first landed on, and the field that meets them there (½‖Ls‖² = 0.060) is
// rougher than the truth (0.040). With 10 point-to-plane iterations first
// (PointToPlaneIterationsLetIcpMarkersSlide) it reaches a field 40x smoother than the truth
// (0.0011) through the same markers, 3.0% off at the vertices and point to surface (0.22% mean,
// correlation 0.97; point to surface 2.5% of the truth's own diagonal, which the test checks): 14
// unlabelled points do not pin this truth down. With known correspondences (landmarks at the same
// 14 vertices) it is 0.61%; on a 12,288-tet bar (5%: 57 markers) point to plane gives 1.0% point to
// surface (3.4% at the vertices). There, which 57 markers are drawn decides it: 0.22% to 4.9% of
// the truth's diagonal over four random draws, the large errors at the free end, one of them a
// local minimum and one a minimum that is itself off (PrintIcpGroundTruthMarkerDraws below;
// docs/registration.md, "Which markers are drawn decides it"). The same four draws as landmarks
// are all within 0.15-0.30% (LandmarkGroundTruth below).
TEST(GaussNewton, DISABLED_RecoversAKnownPlasticFieldFromIcpMarkers) {
  GaussNewtonOptions options;
  options.icp_point_to_plane_iterations = 10;
  const GroundTruthFit m = register_ground_truth(options);
  EXPECT_LT(m.marker_error, 1e-3);
  EXPECT_LT(m.surface_error_of_truth, 0.005);
  EXPECT_GT(m.correlation, 0.8);
}

// The draws behind docs/registration.md's "Which markers are drawn decides it" (12,288 tets, about
// 1.5 min each: run on demand with --gtest_also_run_disabled_tests --gtest_filter='*MarkerDraws*').
// Measured: seeds 3, 11, 5, 7 give 0.22%, 0.54%, 2.4%, 4.9% of the truth's diagonal from the
// template. Seeds 5 and 7 again from the truth: 1.6% (½‖Ls‖² 0.0012, as from the template: the
// minimum itself is off) and 0.33% (0.0014 against 0.0089 from the template: a local minimum).
// Marker coverage (offline/registration/marker_coverage.hpp) sees none of it: in every draw 0% of
// the area is uncovered or weakly pinned, and the worst error's vertex is 0.2 to 0.8 nominal
// spacings from a marker, pinned along its normal at 3.9x (seed 5) and 5.5x (seed 7) the threshold.
TEST(GaussNewton, DISABLED_PrintIcpGroundTruthMarkerDraws) {
  GaussNewtonOptions options;
  options.icp_point_to_plane_iterations = 10;
  const auto run = [&](unsigned seed, bool from_truth) {
    const GroundTruthFit m =
        register_ground_truth(options, {32, seed, TruthShape::kFlatEnds, from_truth});
    std::cout << "seed " << seed << (from_truth ? ", from the truth" : ", from the template")
              << ": point to surface max " << 100 * m.surface_error_of_truth
              << "% of the truth's diagonal, mean " << 100 * m.surface_mean
              << "% of the rest diagonal, correlation " << m.correlation << ", 0.5|Ls|^2 "
              << m.smoothness << "\n";
    EXPECT_LT(m.marker_error, 1e-3) << "seed " << seed;
  };
  for (unsigned seed : {3u, 11u, 5u, 7u}) run(seed, false);
  for (unsigned seed : {5u, 7u}) run(seed, true);
}

// Fig. 21 as the paper ran it ("we then selected 488 sparse triangle mesh vertices as landmarks"):
// 5% of the surface vertices of the 12,288-tet bar (57) as landmarks, flat-ends truth. Every draw
// tried is asserted, not a chosen one. Measured for seeds 3, 11, 5, 7: point to surface 0.17%,
// 0.15%, 0.30%, 0.25% of the truth's diagonal; at the vertices 0.28%, 0.18%, 0.36%, 0.29% of the
// rest diagonal; correlation 0.9974 to 0.9983; about 50 s each. For the record, not asserted:
// the linear truth gives 0.23%, 0.19%, 0.55%, 0.26%, and 3% landmarks (34) on the flat-ends truth
// 0.51%, 0.20%, 0.35%, 0.33%. What the landmarks carry that ICP markers do not is the position
// along the surface: see DISABLED_RecoversAKnownPlasticFieldFromIcpMarkers above.
class LandmarkGroundTruth : public ::testing::TestWithParam<unsigned> {};

TEST_P(LandmarkGroundTruth, FivePercentLandmarksRecoverTheSurfaceWithinHalfAPercent) {
  GroundTruthCase setup;
  setup.cubes = 32;
  setup.seed = GetParam();
  setup.shape = TruthShape::kFlatEnds;
  setup.landmarks = true;
  const GroundTruthFit m = register_ground_truth(GaussNewtonOptions{}, setup);
  EXPECT_LT(m.marker_error, 1e-4);
  EXPECT_LT(m.surface_error_of_truth, 0.005);
  EXPECT_LT(m.vertex_error, 0.005);  // with correspondence, at the vertices too
  EXPECT_GT(m.correlation, 0.99);
}

INSTANTIATE_TEST_SUITE_P(GaussNewton, LandmarkGroundTruth, ::testing::Values(3u, 11u, 5u, 7u),
                         [](const ::testing::TestParamInfo<unsigned>& draw) {
                           return "Seed" + std::to_string(draw.param);
                         });

// GaussNewtonOptions::icp_point_to_plane_iterations on the acceptance case above: the markers,
// counted point to plane first, let the surface slide under them to a smoother field, and the
// point-to-point iterations after it meet them again. Against the paper's plain ICP stage
// (measured: vertex error 6.7% → 3.0% of the diagonal, point to surface 5.8% → 3.0%, correlation
// 0.73 → 0.97, ½‖Ls‖² 0.060 → 0.0011).
TEST(GaussNewton, PointToPlaneIterationsLetIcpMarkersSlide) {
  const GroundTruthFit plain = register_ground_truth(GaussNewtonOptions{});
  GaussNewtonOptions options;
  options.icp_point_to_plane_iterations = 10;
  const GroundTruthFit sliding = register_ground_truth(options);
  EXPECT_LT(plain.marker_error, 1e-5);
  EXPECT_LT(sliding.marker_error, 1e-5);  // met again by the point-to-point iterations
  EXPECT_LT(sliding.smoothness, 0.1 * plain.smoothness);
  EXPECT_LT(sliding.vertex_error, 0.6 * plain.vertex_error);
  EXPECT_LT(sliding.surface_error, 0.6 * plain.surface_error);
  EXPECT_LT(sliding.surface_mean, 0.5 * plain.surface_mean);
  EXPECT_GT(sliding.correlation, 0.9);
  EXPECT_LT(plain.correlation, sliding.correlation);
}

// The bar's attachments and ICP markers at the first `count` of the truth's candidate vertices.
RegistrationConstraints attached_with_icp_markers(const Bar& bar, const Truth& truth,
                                                  std::size_t count) {
  RegistrationConstraints constraints;
  constraints.attachments = bar.attachments;
  for (std::size_t i = 0; i < count; ++i) {
    constraints.icp_markers.push_back(truth.x.segment<3>(3 * truth.candidates[i]));
  }
  return constraints;
}

// The ICP tests' scene: the bar attached at its ends with 12 ICP markers on its 5 % truth, and the
// closest points on its boundary. A fixture (BoundaryClosestPoint keeps a reference to its query).
class GaussNewtonIcpBar : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(bar.energy.has_value());
    constraints = attached_with_icp_markers(bar, make_truth(bar, 5), 12);
    surface_query = SurfaceClosestPoint::create(bar.mesh.rest_positions.rows(), bar.mesh.tets);
    ASSERT_TRUE(surface_query.has_value());
    boundary.emplace(*surface_query);
  }
  Bar bar = make_bar();
  RegistrationConstraints constraints;
  std::optional<SurfaceClosestPoint> surface_query;
  std::optional<BoundaryClosestPoint> boundary;
};

// The ICP weight ramp (GaussNewtonOptions::icp_weight_ramp): its iterations weigh the markers
// by the factors (the objective before the first ICP iteration is the smoothness plus factor·the
// plain run's marker term, at the same state), the stopping tests wait for the full weight, and
// the stage still ends with its markers met.
TEST_F(GaussNewtonIcpBar, IcpWeightRampWeighsTheFirstIterationsLessAndStopsOnlyAtFullWeight) {
  BoundaryClosestPoint& closest = *boundary;
  GaussNewtonOptions plain;
  plain.max_iterations_per_stage = 8;
  plain.max_marker_error = 2e-3;  // 2 mm: met after the first full-weight iteration
  const RegistrationResult a = register_attached(*bar.energy, constraints, &closest, plain);
  GaussNewtonOptions ramped = plain;
  ramped.icp_weight_ramp = {1e-2, 1e-1, 1e-1};
  const RegistrationResult b = register_attached(*bar.energy, constraints, &closest, ramped);
  ASSERT_TRUE(a.summary.usable() && b.summary.usable()) << b.summary.full_report();

  auto icp = [](const RegistrationResult& r) {
    std::vector<GaussNewtonIteration> list;
    for (const GaussNewtonIteration& it : r.summary.iterations) {
      if (it.stage == RegistrationStage::kIcpMarkers) list.push_back(it);
    }
    return list;
  };
  const auto plain_icp = icp(a), ramped_icp = icp(b);
  ASSERT_FALSE(plain_icp.empty());
  // Both runs enter the ICP stage from the same initial fit; the objective there is
  // ½‖Ls‖² (0: the initial fit leaves s uniform) + the attachment term (β, not ramped: small
  // here) + weight·markers.
  const double factor = ramped_icp.front().objective_before / plain_icp.front().objective_before;
  EXPECT_NEAR(factor, 1e-2, 1e-4);
  EXPECT_EQ(a.summary.termination, GaussNewtonTermination::kMarkerTolerance);
  EXPECT_EQ(b.summary.termination, GaussNewtonTermination::kMarkerTolerance);
  // The plain run stops as soon as the tolerance holds; the ramped one not before its ramp ends.
  EXPECT_GT(ramped_icp.size(), ramped.icp_weight_ramp.size());
  EXPECT_LE(b.summary.marker_error_max, plain.max_marker_error);

  GaussNewtonOptions bad = ramped;
  bad.icp_weight_ramp = {0.5, 0.0};
  ASSERT_TRUE(bad.validate().has_value());
  EXPECT_NE(bad.validate()->find("icp_weight_ramp[1] = 0"), std::string::npos) << *bad.validate();
  bad.icp_weight_ramp = {1.5};
  EXPECT_TRUE(bad.validate().has_value());
}

// A stall is not convergence (issue 51): a stage that stops by its small-decrease (or small-step)
// test with the markers on average farther than the marker tolerance ends kStalled, a failure,
// with a one-line message; without a tolerance (0) the same run ends kSmallDecrease as before.
TEST_F(GaussNewtonIcpBar, SmallDecreaseWithMarkersFarFromTheToleranceIsAStall) {
  BoundaryClosestPoint& closest = *boundary;
  GaussNewtonOptions options;
  options.max_iterations_per_stage = 8;
  // Any iteration that lowers Φ by less than 90 % ends the stage by small-decrease.
  options.relative_decrease_tolerance = 0.9;
  const RegistrationResult plain = register_attached(*bar.energy, constraints, &closest, options);
  ASSERT_TRUE(plain.summary.usable()) << plain.summary.full_report();
  EXPECT_EQ(plain.summary.termination, GaussNewtonTermination::kSmallDecrease)
      << plain.summary.full_report();
  EXPECT_FALSE(plain.summary.failed());
  // The same run with a tolerance far below where it stopped: a stall.
  options.max_marker_error = 1e-3 * plain.summary.marker_error_mean;
  const RegistrationResult stalled = register_attached(*bar.energy, constraints, &closest, options);
  EXPECT_EQ(stalled.summary.termination, GaussNewtonTermination::kStalled)
      << stalled.summary.full_report();
  EXPECT_TRUE(stalled.summary.failed());
  EXPECT_TRUE(stalled.summary.usable());  // the state is there to look at
  EXPECT_EQ(std::string(to_string(stalled.summary.termination)), "stalled");
  EXPECT_NE(stalled.summary.message.find("stalled: the icp stage ended by small-decrease"),
            std::string::npos)
      << stalled.summary.message;
  EXPECT_EQ(stalled.summary.message.find('\n'), std::string::npos);
  // With a tolerance the markers meet on average, not a stall.
  options.max_marker_error = 10.0 * plain.summary.marker_error_mean;
  const RegistrationResult met = register_attached(*bar.energy, constraints, &closest, options);
  EXPECT_NE(met.summary.termination, GaussNewtonTermination::kStalled);
  EXPECT_FALSE(met.summary.failed());
}

// The trust region on the damped steps' constant-strain part (GaussNewtonOptions::
// constant_strain_step_limit, issue 51): L² does not damp the six constant strains Ψ, so as μ grows
// the damped step tends to the Gauss–Newton step along Ψ instead of to 0 (the bunny bulged 2×: a
// mean change of 0.44 in s at μ = 1e6 whose equilibria all failed). One ICP iteration from the
// template (s = I, the attachments hold it at rest), resumed after an iteration that took μ = 1e7
// (so it starts at 1e6): without the limit the step moves the mean of s by over a tenth of the
// undamped step's mean; with it by η·limit·‖mean of s‖/√(1 + μ) (the limit binds), Φ still
// falls, and an undamped step is the same bits with or without the limit.
TEST_F(GaussNewtonIcpBar, TheConstantStrainLimitShrinksTheDampedStepsMeanToo) {
  BoundaryClosestPoint& closest = *boundary;
  const Eigen::Index m = bar.mesh.tets.rows();
  const Eigen::VectorXd identity = identity_plastic_strains(m);
  auto one_icp_iteration = [&](double damping_before, int trials, double limit,
                               double min_damping = 0.0) {
    GaussNewtonCheckpoint start;
    start.next_stage = RegistrationStage::kIcpMarkers;
    start.s = identity;
    start.x = bar.energy->rest_dofs();
    GaussNewtonIteration previous;
    previous.iteration = 1;
    previous.damping = damping_before;
    start.iterations = {previous};
    start.initial_objective = 1.0;
    GaussNewtonOptions options;
    options.max_iterations_per_stage = 1;
    options.damped_step_trials = trials;
    options.constant_strain_step_limit = limit;
    options.rescue_min_damping = min_damping;
    return register_attached(*bar.energy, constraints, &closest, options, {}, {}, &start);
  };
  auto mean_change = [&](const Eigen::VectorXd& s) {
    Eigen::Matrix<double, 6, 1> sum = Eigen::Matrix<double, 6, 1>::Zero();
    for (Eigen::Index t = 0; t < m; ++t) sum += s.segment<6>(6 * t) - identity.segment<6>(6 * t);
    return (sum / static_cast<double>(m)).norm();
  };
  const double limit = 0.05;
  const RegistrationResult plain = one_icp_iteration(0.0, 0, 0.0);
  const RegistrationResult plain_limited = one_icp_iteration(0.0, 0, limit);
  const RegistrationResult damped = one_icp_iteration(1e7, 1, 0.0);
  const RegistrationResult limited = one_icp_iteration(1e7, 1, limit);
  for (const RegistrationResult* r : {&plain, &plain_limited, &damped, &limited})
    ASSERT_TRUE(r->summary.usable()) << r->summary.full_report();
  EXPECT_EQ(plain.s, plain_limited.s);  // μ = 0: untouched
  const double plain_mean = mean_change(plain.s);
  ASSERT_GT(plain_mean, 1e-3) << "the undamped step changes the constant strains";
  const GaussNewtonIteration& it = limited.summary.iterations.back();
  ASSERT_GE(it.damping, 1e6);
  ASSERT_GT(it.step, 0.0);
  EXPECT_GT(mean_change(damped.s), 0.1 * plain_mean);
  // ‖mean of s‖ = ‖(1, 0, 0, 1, 0, 1)‖ = √3 at the template.
  const double bound = it.step * limit * std::sqrt(3.0) / std::sqrt(1.0 + it.damping);
  EXPECT_NEAR(mean_change(limited.s), bound, 1e-6 * bound);
  EXPECT_LT(it.objective, it.objective_before);
  // The limit acts only on steps damped at μ ≥ rescue_min_damping: from
  // 1e8 on it leaves these steps (μ = 1e6 or 1e7) the same bits as without it, from 1e6 on it
  // binds as above.
  const RegistrationResult below = one_icp_iteration(1e7, 1, limit, 1e8);
  const RegistrationResult from = one_icp_iteration(1e7, 1, limit, 1e6);
  ASSERT_TRUE(below.summary.usable()) << below.summary.full_report();
  ASSERT_TRUE(from.summary.usable()) << from.summary.full_report();
  EXPECT_EQ(below.s, damped.s);
  EXPECT_EQ(from.s, limited.s);
}

// Held tets (hold_clamped_tets) by penalty rows or, once those rows would take more than
// held_penalty_max_bytes, by elimination (issue 51: the bunny bent 90° was killed at 22 GB holding
// hundreds of tets by six rows each). One ICP iteration from the template with an eigenvalue
// floor just below 1, so that the plain step clamps tets and the step is solved again holding
// them: with the bytes unbounded the rows hold them, with 0 elimination does, the report says
// which, the held tets' s stays at the template's in both, and the two steps agree to the
// penalty's stiffness (1e3 times the largest row: 1e-6 of the held curvature).
TEST_F(GaussNewtonIcpBar, ManyHeldTetsAreHeldByEliminationWithoutPenaltyRows) {
  BoundaryClosestPoint& closest = *boundary;
  const Eigen::Index m = bar.mesh.tets.rows();
  const Eigen::VectorXd identity = identity_plastic_strains(m);
  auto one_icp_iteration = [&](double max_bytes) {
    GaussNewtonCheckpoint start;
    start.next_stage = RegistrationStage::kIcpMarkers;
    start.s = identity;
    start.x = bar.energy->rest_dofs();
    start.initial_objective = 1.0;
    GaussNewtonOptions options;
    options.max_iterations_per_stage = 1;
    options.hold_clamped_tets = true;
    options.eigenvalue_floor = 0.999;
    options.held_penalty_max_bytes = max_bytes;
    return register_attached(*bar.energy, constraints, &closest, options, {}, {}, &start);
  };
  const RegistrationResult rows = one_icp_iteration(1e300);
  const RegistrationResult eliminated = one_icp_iteration(0.0);
  ASSERT_TRUE(rows.summary.usable()) << rows.summary.full_report();
  ASSERT_TRUE(eliminated.summary.usable()) << eliminated.summary.full_report();
  const GaussNewtonIteration& a = rows.summary.iterations.back();
  const GaussNewtonIteration& b = eliminated.summary.iterations.back();
  ASSERT_GT(a.held_tets, 0) << rows.summary.full_report();
  EXPECT_EQ(a.held_tets, b.held_tets);
  EXPECT_FALSE(a.held_by_elimination);
  EXPECT_TRUE(b.held_by_elimination);
  ASSERT_GT(b.step, 0.0);
  EXPECT_LT(b.objective, b.objective_before);
  const double change = (rows.s - identity).norm();
  ASSERT_GT(change, 0.0);
  EXPECT_LT((eliminated.s - rows.s).norm(), 1e-3 * change);
  GaussNewtonOptions bad;
  bad.held_penalty_max_bytes = -1.0;
  EXPECT_TRUE(bad.validate().has_value());
}

// Attachments far from the template (the far end of a bar twisted by 135° about its axis, as in
// the Botsch–Sorkine benchmark): the direct first equilibrium fails, the load-stepped one
// succeeds.
TEST(GaussNewton, FarAttachmentsAreReachedByLoadSteps) {
  Bar bar = make_bar();
  const double angle = 135.0 * EIGEN_PI / 180.0;
  const Eigen::Vector3d axis_point(0.0, 0.0375, 0.0375);
  for (int v = 0; v < bar.mesh.rest_positions.rows(); ++v) {
    const Eigen::Vector3d X = bar.mesh.rest_positions.row(v).transpose();
    if (X.x() < bar.length - 1e-9) continue;
    PointConstraint c;
    c.kind = ConstraintKind::kAttachment;
    c.point = at_vertex(bar.mesh.tets, v);
    c.target = axis_point + Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitX()) * (X - axis_point);
    c.weight = 1e4;
    bar.attachments.push_back(c);
  }
  RegistrationConstraints constraints;
  constraints.attachments = bar.attachments;
  GaussNewtonOptions options;
  options.initial_constant_fit = false;
  options.max_iterations_per_stage = 0;
  // Newton is robust enough to reach this twist directly in its default 100 iterations; with a
  // budget of 6 per solve (standing in for a harder case) only the load steps get there.
  options.equilibrium.max_iterations = 6;
  options.first_equilibrium_steps = 1;
  const RegistrationResult direct = register_attached(*bar.energy, constraints, nullptr, options);
  std::cout << "direct: " << direct.summary.brief_report() << "\n";
  EXPECT_EQ(direct.summary.termination, GaussNewtonTermination::kEquilibriumFailed);
  options.first_equilibrium_steps = 16;
  const RegistrationResult stepped = register_attached(*bar.energy, constraints, nullptr, options);
  std::cout << "stepped: " << stepped.summary.brief_report() << "\n";
  ASSERT_TRUE(stepped.summary.usable()) << stepped.summary.message;
  double worst = 0.0;
  for (const PointConstraint& c : bar.attachments) {
    worst =
        std::max(worst, (embedded_position(bar.mesh.tets, c.point, stepped.x) - c.target).norm());
  }
  EXPECT_LT(worst, 0.002);  // the springs hold the twisted end to 2 mm of 7.5 cm
}

// Resuming from any checkpoint gives the uninterrupted run's result bit for bit: after the initial
// fit the loop's state is (s, x) and its position. Also with a first equilibrium that needed load
// steps (the spring targets must not keep a trace of them).
TEST(GaussNewton, ResumingFromEveryCheckpointGivesTheUninterruptedResult) {
  for (const bool twisted : {false, true}) {
    SCOPED_TRACE(twisted ? "twisted, load-stepped first equilibrium" : "landmarks");
    Bar bar = make_bar();
    const Truth truth = make_truth(bar, 7);
    RegistrationConstraints constraints;
    GaussNewtonOptions options;
    options.max_iterations_per_stage = 3;
    if (twisted) {
      for (int v = 0; v < bar.mesh.rest_positions.rows(); ++v) {
        const Eigen::Vector3d X = bar.mesh.rest_positions.row(v).transpose();
        if (X.x() < bar.length - 1e-9) continue;
        PointConstraint c;
        c.kind = ConstraintKind::kAttachment;
        c.point = at_vertex(bar.mesh.tets, v);
        c.target = Eigen::Vector3d(0.0, 0.0375, 0.0375) +
                   Eigen::AngleAxisd(1.2, Eigen::Vector3d::UnitX()) *
                       (X - Eigen::Vector3d(0.0, 0.0375, 0.0375));
        c.weight = 1e4;
        bar.attachments.push_back(c);
      }
      options.equilibrium.max_iterations = 6;  // the direct first solve fails: load steps
      options.beta = 1e3;
      GaussNewtonOptions direct = options;
      direct.first_equilibrium_steps = 1;
      direct.initial_constant_fit = false;
      direct.max_iterations_per_stage = 0;
      RegistrationConstraints springs_only;
      springs_only.attachments = bar.attachments;
      ASSERT_EQ(register_attached(*bar.energy, springs_only, nullptr, direct).summary.termination,
                GaussNewtonTermination::kEquilibriumFailed);
    }
    constraints.attachments = bar.attachments;
    for (std::size_t i = 0; i < 20; ++i) {
      PointConstraint c;
      c.kind = ConstraintKind::kLandmark;
      c.point = at_vertex(bar.mesh.tets, truth.candidates[i]);
      c.target = truth.x.segment<3>(3 * truth.candidates[i]) +
                 (twisted ? Eigen::Vector3d(0, 0, 0.002) : Eigen::Vector3d::Zero());
      constraints.landmarks.push_back(c);
    }
    std::vector<GaussNewtonCheckpoint> checkpoints;
    const RegistrationResult whole =
        register_attached(*bar.energy, constraints, nullptr, options, {},
                          [&](const GaussNewtonCheckpoint& c) { checkpoints.push_back(c); });
    ASSERT_TRUE(whole.summary.usable()) << whole.summary.full_report();
    std::cout << whole.summary.full_report();
    // One checkpoint after the initial fit and one per iteration; the last one has nothing left.
    ASSERT_EQ(checkpoints.size(), whole.summary.iterations.size());
    ASSERT_GE(checkpoints.size(), 3u);
    EXPECT_EQ(checkpoints.front().iterations.size(), 1u);
    EXPECT_EQ(checkpoints.front().next_stage, RegistrationStage::kAttachments);
    EXPECT_EQ(checkpoints.front().next_iteration, 1);
    EXPECT_FALSE(checkpoints.back().next_stage.has_value());
    EXPECT_EQ(checkpoints.back().termination, whole.summary.termination);
    for (std::size_t k = 0; k < checkpoints.size(); ++k) {
      SCOPED_TRACE(k);
      const RegistrationResult resumed =
          register_attached(*bar.energy, constraints, nullptr, options, {}, {}, &checkpoints[k]);
      ASSERT_TRUE(resumed.summary.usable()) << resumed.summary.message;
      EXPECT_EQ((resumed.s - whole.s).lpNorm<Eigen::Infinity>(), 0.0);
      EXPECT_EQ((resumed.x - whole.x).lpNorm<Eigen::Infinity>(), 0.0);
      EXPECT_EQ(resumed.summary.final_objective, whole.summary.final_objective);
      EXPECT_EQ(resumed.summary.initial_objective, whole.summary.initial_objective);
      EXPECT_EQ(resumed.summary.termination, whole.summary.termination);
      EXPECT_EQ(resumed.summary.iterations.size(), whole.summary.iterations.size());
      EXPECT_EQ(resumed.summary.equilibrium_solves, whole.summary.equilibrium_solves);
    }
    // A checkpoint that does not fit is an input error.
    GaussNewtonCheckpoint wrong = checkpoints.front();
    wrong.x.conservativeResize(wrong.x.size() - 3);
    const RegistrationResult refused =
        register_attached(*bar.energy, constraints, nullptr, options, {}, {}, &wrong);
    EXPECT_EQ(refused.summary.termination, GaussNewtonTermination::kInvalidInput);
    EXPECT_NE(refused.summary.message.find("checkpoint: s has"), std::string::npos)
        << refused.summary.message;
    wrong = checkpoints.front();
    wrong.free_object = true;
    EXPECT_EQ(register_attached(*bar.energy, constraints, nullptr, options, {}, {}, &wrong)
                  .summary.message,
              "checkpoint: written by register_free, resumed by register_attached");
  }
}

TEST(GaussNewton, BadInputsAreStatuses) {
  Bar bar = make_bar();
  RegistrationConstraints constraints;
  RegistrationResult result = register_attached(*bar.energy, constraints, nullptr);
  EXPECT_EQ(result.summary.termination, GaussNewtonTermination::kInvalidInput);
  EXPECT_NE(result.summary.message.find("attachments"), std::string::npos);
  constraints.attachments = bar.attachments;
  constraints.icp_markers.push_back(Eigen::Vector3d::Zero());
  result = register_attached(*bar.energy, constraints, nullptr);
  EXPECT_EQ(result.summary.termination, GaussNewtonTermination::kInvalidInput);
  EXPECT_NE(result.summary.message.find("closest"), std::string::npos);
  GaussNewtonOptions options;
  options.min_step = 2.0;
  constraints.icp_markers.clear();
  result = register_attached(*bar.energy, constraints, nullptr, options);
  EXPECT_EQ(result.summary.termination, GaussNewtonTermination::kInvalidInput);
  EXPECT_NE(result.summary.message.find("min_step = 2"), std::string::npos)
      << result.summary.message;
}

}  // namespace
}  // namespace sinew::offline
