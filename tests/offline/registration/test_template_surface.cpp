// offline/registration/template_surface: ICP closest points on the template's own surface, as
// material points that move with the deformation.
#include "offline/registration/template_surface.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace {

using sinew::offline::EmbeddedPoint;
using sinew::offline::TemplateSurfaceClosestPoint;
using sinew::offline::TetPointLocator;

// One tet, its four faces the template surface, each surface vertex a mesh vertex.
struct OneTet {
  sinew::common::TetIndices tets{1, 4};
  Eigen::MatrixXd rest{4, 3};
  Eigen::MatrixXi triangles{4, 3};
  std::vector<EmbeddedPoint> vertex_points;
  OneTet() {
    tets << 0, 1, 2, 3;
    rest << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
    triangles << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3;
    for (int v = 0; v < 4; ++v) {
      EmbeddedPoint p;
      p.tet = 0;
      p.weights = Eigen::Vector4d::Unit(v);
      vertex_points.push_back(p);
    }
  }
  Eigen::VectorXd dofs(const Eigen::Matrix3d& F) const {
    Eigen::VectorXd x(12);
    for (int v = 0; v < 4; ++v) x.segment<3>(3 * v) = F * rest.row(v).transpose();
    return x;
  }
};

TEST(TemplateSurfaceClosestPoint, ClosestPointsAreMaterialPointsThatMoveWithTheDeformation) {
  const OneTet m;
  const auto locator = TetPointLocator::create(m.rest, m.tets);
  ASSERT_TRUE(locator);
  const Eigen::VectorXd rest = m.dofs(Eigen::Matrix3d::Identity());
  TemplateSurfaceClosestPoint closest(m.tets, rest, *locator, m.triangles, m.vertex_points);

  closest.update(rest);
  const EmbeddedPoint below = closest.closest(Eigen::Vector3d(0.2, 0.3, -1.0));
  EXPECT_LT(
      (sinew::offline::embedded_position(m.tets, below, rest) - Eigen::Vector3d(0.2, 0.3, 0.0))
          .norm(),
      1e-12);
  EXPECT_NEAR(std::abs(closest.normal(Eigen::Vector3d(0.2, 0.3, -1.0)).z()), 1.0, 1e-12);

  // Stretched 2x along x: the query's closest point on the deformed surface is (0.6, 0.3, 0),
  // the image of the template point (0.3, 0.3, 0).
  const Eigen::Matrix3d F = Eigen::Vector3d(2.0, 1.0, 1.0).asDiagonal();
  const Eigen::VectorXd x = m.dofs(F);
  closest.update(x);
  const EmbeddedPoint p = closest.closest(Eigen::Vector3d(0.6, 0.3, -0.5));
  EXPECT_LT(
      (sinew::offline::embedded_position(m.tets, p, x) - Eigen::Vector3d(0.6, 0.3, 0.0)).norm(),
      1e-12);
  EXPECT_LT(
      (sinew::offline::embedded_position(m.tets, p, rest) - Eigen::Vector3d(0.3, 0.3, 0.0)).norm(),
      1e-12);
  // On the slanted face x + y + z = 1, stretched: its normal is that of 0.5x + y + z = 1.
  const Eigen::Vector3d on_face = F * Eigen::Vector3d(0.2, 0.3, 0.5);
  const Eigen::Vector3d n = closest.normal(on_face);
  EXPECT_NEAR(std::abs(n.dot(Eigen::Vector3d(0.5, 1.0, 1.0).normalized())), 1.0, 1e-9) << n;
}

}  // namespace
