// offline::SurfaceDistance (sinew-register --truth, the ICP closest points on a template surface):
// its grid-accelerated closest point agrees with a brute-force search over every triangle, near
// the surface and far from it. The surface is the demo case's truth (tools/register/demo_case).
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <limits>
#include <random>

#include "offline/meshing/surface_closest_point.hpp"
#include "offline/registration/surface_distance.hpp"
#include "tools/register/demo_case.hpp"

namespace {

using sinew::offline::io::SurfaceMesh;

TEST(SurfaceDistance, MatchesBruteForce) {
  const sinew::tools::DemoCase demo = sinew::tools::make_demo_case();
  const SurfaceMesh& truth = demo.truth_surface;
  const sinew::offline::SurfaceDistance query(truth);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> uniform(-80.0, 180.0);
  double largest = 0.0;
  for (int i = 0; i < 300; ++i) {
    // Near the surface (jittered vertices) and far from it (anywhere in a box around it).
    const Eigen::Vector3d p =
        i % 2 == 0 ? Eigen::Vector3d(truth.vertices.row(i % truth.vertices.rows()).transpose() +
                                     Eigen::Vector3d(uniform(rng), uniform(rng), uniform(rng)) / 50)
                   : Eigen::Vector3d(uniform(rng), uniform(rng), uniform(rng));
    double brute = std::numeric_limits<double>::infinity();
    for (Eigen::Index f = 0; f < truth.triangles.rows(); ++f)
      brute = std::min(brute, (sinew::offline::closest_point_on_triangle(
                                   p, truth.vertices.row(truth.triangles(f, 0)).transpose(),
                                   truth.vertices.row(truth.triangles(f, 1)).transpose(),
                                   truth.vertices.row(truth.triangles(f, 2)).transpose())
                                   .point -
                               p)
                                  .norm());
    EXPECT_NEAR(query.distance(p), brute, 1e-12 * (1 + brute)) << i;
    largest = std::max(largest, brute);
  }
  EXPECT_GT(largest, 10.0);  // the far points tested the ring search
}

}  // namespace
