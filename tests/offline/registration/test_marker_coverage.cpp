// Tests of offline/marker_coverage: nearest-data-point distances against brute force, the
// nominal spacing, the uncovered area against a shape whose area is known in closed form, the
// pinning against its closed form, and a bar whose ICP markers on the sides leave its free end
// free along the bar.

#include "offline/registration/marker_coverage.hpp"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <iostream>
#include <limits>
#include <random>
#include <vector>

#include "offline/meshing/surface_closest_point.hpp"
#include "tests/support/tet_mesh_fixtures.hpp"

namespace {

using sinew::offline::marker_coverage;
using sinew::offline::MarkerCoverage;
using sinew::offline::MarkerCoverageOptions;

// The unit square in z = 0 as an n x n grid of vertices, two triangles per cell.
struct Grid {
  Eigen::MatrixXd vertices;
  Eigen::MatrixXi triangles;
};

Grid unit_square(int n) {
  Grid g;
  g.vertices.resize(n * n, 3);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i)
      g.vertices.row(j * n + i) << static_cast<double>(i) / (n - 1),
          static_cast<double>(j) / (n - 1), 0.0;
  g.triangles.resize(2 * (n - 1) * (n - 1), 3);
  int f = 0;
  for (int j = 0; j + 1 < n; ++j) {
    for (int i = 0; i + 1 < n; ++i) {
      const int a = j * n + i;
      g.triangles.row(f++) << a, a + 1, a + n + 1;
      g.triangles.row(f++) << a, a + n + 1, a + n;
    }
  }
  return g;
}

TEST(MarkerCoverage, DistancesMatchBruteForce) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> uniform(-1.0, 2.0);
  Grid g = unit_square(21);
  for (Eigen::Index v = 0; v < g.vertices.rows(); ++v) g.vertices(v, 2) = 0.3 * uniform(rng);
  std::vector<Eigen::Vector3d> points;
  for (int k = 0; k < 37; ++k) points.emplace_back(uniform(rng), uniform(rng), uniform(rng));
  points.push_back(points[5]);  // a repeated point changes nothing
  const MarkerCoverage c = marker_coverage(g.vertices, g.triangles, points, {});
  ASSERT_EQ(c.distance.size(), g.vertices.rows());
  double farthest = 0.0;
  for (Eigen::Index v = 0; v < g.vertices.rows(); ++v) {
    double brute = std::numeric_limits<double>::infinity();
    for (const Eigen::Vector3d& p : points)
      brute = std::min(brute, (p - g.vertices.row(v).transpose()).norm());
    EXPECT_DOUBLE_EQ(c.distance[v], brute) << v;
    farthest = std::max(farthest, brute);
  }
  EXPECT_DOUBLE_EQ(c.max_distance, farthest);
  EXPECT_DOUBLE_EQ(c.distance[c.farthest_vertex], farthest);
}

TEST(MarkerCoverage, CornerMarkerLeavesTheAreaOutsideAQuarterDiscUncovered) {
  const Grid g = unit_square(201);
  const std::vector<Eigen::Vector3d> corner = {Eigen::Vector3d::Zero()};
  MarkerCoverageOptions options;
  options.uncovered_spacings = 0.5;  // one marker on area 1: spacing 1, radius 0.5
  const MarkerCoverage c = marker_coverage(g.vertices, g.triangles, corner, {}, 1, options);
  EXPECT_NEAR(c.area, 1.0, 1e-12);
  EXPECT_NEAR(c.nominal_spacing, 1.0, 1e-12);
  EXPECT_NEAR(c.uncovered_area_fraction, 1.0 - EIGEN_PI / 16.0, 2e-3);  // 0.804
  EXPECT_NEAR(c.max_distance, std::sqrt(2.0), 1e-12);                   // the opposite corner
  EXPECT_EQ(c.farthest_vertex, g.vertices.rows() - 1);
}

TEST(MarkerCoverage, NominalSpacingCountsTheMarkersNotTheAttachments) {
  const Grid g = unit_square(11);
  // 4 markers plus 11 attachment targets along the edge y = 0.
  std::vector<Eigen::Vector3d> points = {
      {0.25, 0.25, 0}, {0.75, 0.25, 0}, {0.25, 0.75, 0}, {0.75, 0.75, 0}};
  for (int i = 0; i <= 10; ++i) points.emplace_back(0.1 * i, 0.0, 0.0);
  const MarkerCoverage markers_only = marker_coverage(g.vertices, g.triangles, points, {}, 4);
  EXPECT_NEAR(markers_only.nominal_spacing, 0.5, 1e-12);
  // Every vertex is within 0.5 · √2 / 2 ≈ 0.354 of a marker: nothing is farther than 1.5 · 0.5.
  EXPECT_EQ(markers_only.uncovered_area_fraction, 0.0);
  EXPECT_NEAR(markers_only.max_distance, std::sqrt(2.0) / 4.0, 1e-12);
  const MarkerCoverage all = marker_coverage(g.vertices, g.triangles, points, {});
  EXPECT_NEAR(all.nominal_spacing, std::sqrt(1.0 / 15.0), 1e-12);
}

TEST(MarkerCoverage, VerticesOfNoTriangleGetADistanceButDoNotCountAsFarthest) {
  Grid g = unit_square(11);
  g.vertices.conservativeResize(g.vertices.rows() + 1, 3);
  g.vertices.row(g.vertices.rows() - 1) << 0.5, 0.5, -5.0;  // like a tet mesh's interior vertex
  const std::vector<Eigen::Vector3d> centre = {Eigen::Vector3d(0.5, 0.5, 0.0)};
  const MarkerCoverage c = marker_coverage(g.vertices, g.triangles, centre, {});
  EXPECT_DOUBLE_EQ(c.distance[g.vertices.rows() - 1], 5.0);
  EXPECT_NEAR(c.max_distance, std::sqrt(0.5), 1e-12);  // a corner of the square
  EXPECT_NEAR(c.area, 1.0, 1e-12);
}

TEST(MarkerCoverage, NoPointsLeavesEverythingUncovered) {
  const Grid g = unit_square(5);
  const MarkerCoverage c = marker_coverage(g.vertices, g.triangles, {}, {});
  EXPECT_TRUE(std::isinf(c.max_distance));
  EXPECT_NEAR(c.uncovered_area_fraction, 1.0, 1e-12);
  EXPECT_NEAR(c.weakly_pinned_area_fraction, 1.0, 1e-12);
  EXPECT_EQ(c.nominal_spacing, 0.0);
}

TEST(MarkerCoverage, PinningIsTheGaussianWeightOfALandmarkOrOfAnIcpMarkerAlongTheNormal) {
  const Grid g = unit_square(11);  // area 1; one marker: spacing 1
  const std::vector<Eigen::Vector3d> centre = {Eigen::Vector3d(0.5, 0.5, 0.0)};
  const MarkerCoverage landmark = marker_coverage(g.vertices, g.triangles, centre, {});
  for (Eigen::Index v = 0; v < g.vertices.rows(); ++v) {
    const double r2 = (g.vertices.row(v).transpose() - centre[0]).squaredNorm();
    EXPECT_NEAR(landmark.pinning[v], std::exp(-0.5 * r2), 1e-12) << v;
  }
  EXPECT_NEAR(landmark.min_pinning, std::exp(-0.25), 1e-12);  // the corners, √0.5 away
  EXPECT_NEAR(landmark.pinning_threshold, std::exp(-1.125), 1e-15);
  EXPECT_EQ(landmark.weakly_pinned_area_fraction, 0.0);
  // On a plane an ICP marker's normal is the plane's: it pins the same.
  const MarkerCoverage flat = marker_coverage(g.vertices, g.triangles, {}, centre);
  EXPECT_TRUE(flat.pinning.isApprox(landmark.pinning, 1e-12));
}

// A 0.2 x 0.05 x 0.05 bar, its x = 0 end attached. ICP markers evenly on its four sides hold the
// sides where they are, but the free end's face (normal along the bar) is held by nothing until
// markers lie on that face itself: with only side markers it may move along the bar, and the
// distance to the nearest marker does not show it.
TEST(MarkerCoverage, SideMarkersLeaveTheFreeEndFaceUnpinned) {
  const sinew::testing::TetMesh bar = sinew::testing::make_box_mesh(16, 4, 4, 0.0125);
  auto boundary = sinew::offline::BoundarySurface::extract(bar.rest_positions.rows(), bar.tets);
  ASSERT_TRUE(boundary.has_value());
  const Eigen::MatrixXi triangles = boundary->triangles();
  std::vector<Eigen::Vector3d> attachments, sides;
  for (Eigen::Index v = 0; v < bar.rest_positions.rows(); ++v) {
    const Eigen::Vector3d X = bar.rest_positions.row(v).transpose();
    if (X.x() == 0.0) attachments.push_back(X);
  }
  for (int i = 0; i < 10; ++i) {
    const double x = 0.01 + 0.02 * i;  // up to 0.19, next to the free end
    for (const Eigen::Vector3d& p :
         {Eigen::Vector3d(x, 0.0, 0.025), Eigen::Vector3d(x, 0.05, 0.025),
          Eigen::Vector3d(x, 0.025, 0.0), Eigen::Vector3d(x, 0.025, 0.05)})
      sides.push_back(p);
  }
  const auto end_face_pinning = [&](const MarkerCoverage& c) {
    double most = 0.0;
    for (Eigen::Index v = 0; v < bar.rest_positions.rows(); ++v)
      if (bar.rest_positions(v, 0) == 0.2) most = std::max(most, c.pinning[v]);
    return most;
  };
  const MarkerCoverage c =
      marker_coverage(bar.rest_positions, triangles, attachments, sides, sides.size());
  // Every vertex is within 1.5 spacings of a marker: by distance alone, nothing is uncovered.
  EXPECT_EQ(c.uncovered_area_fraction, 0.0);
  // The end face's centre is held by nothing (its corners a little, by their averaged normals).
  const Eigen::Index end_centre = 16 + 17 * (2 + 5 * 2);
  ASSERT_TRUE(bar.rest_positions.row(end_centre).isApprox(Eigen::RowVector3d(0.2, 0.025, 0.025)));
  EXPECT_LT(c.pinning[end_centre], 1e-3 * c.pinning_threshold);
  EXPECT_EQ(bar.rest_positions(c.weakest_vertex, 0), 0.2);
  EXPECT_GT(c.weakly_pinned_area_fraction, 0.02);  // the end face is 5.6% of the area
  // The sides are held: every side vertex away from the end face is pinned.
  for (Eigen::Index v = 0; v < bar.rest_positions.rows(); ++v) {
    const Eigen::Vector3d X = bar.rest_positions.row(v).transpose();
    const bool side = X.y() == 0.0 || X.y() == 0.05 || X.z() == 0.0 || X.z() == 0.05;
    if (side && X.x() < 0.19) {
      EXPECT_GT(c.pinning[v], c.pinning_threshold) << X.transpose();
    }
  }
  // Three markers on the end face pin it.
  std::vector<Eigen::Vector3d> with_end = sides;
  for (const Eigen::Vector3d& p :
       {Eigen::Vector3d(0.2, 0.01, 0.01), Eigen::Vector3d(0.2, 0.04, 0.01),
        Eigen::Vector3d(0.2, 0.025, 0.04)})
    with_end.push_back(p);
  const MarkerCoverage d =
      marker_coverage(bar.rest_positions, triangles, attachments, with_end, with_end.size());
  EXPECT_GT(d.pinning[end_centre], d.pinning_threshold);
  EXPECT_LT(d.weakly_pinned_area_fraction, 0.01);
  std::cout << "side markers only: end face pinned at most " << end_face_pinning(c)
            << " (threshold " << c.pinning_threshold << "), weakly pinned area "
            << 100 * c.weakly_pinned_area_fraction << "%; with three on the end face: at most "
            << end_face_pinning(d) << ", " << 100 * d.weakly_pinned_area_fraction << "%\n";
}

}  // namespace
