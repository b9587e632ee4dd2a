// Tests of offline/surface_closest_point: boundary extraction (outward faces, tet and slots),
// closest points on the deformed boundary against a brute-force reference, the embedded points of
// the ICP markers (seed 003, §3.4), and the failure statuses.
#include "offline/meshing/surface_closest_point.hpp"

#include <Eigen/Geometry>

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "tests/support/tet_mesh_fixtures.hpp"

namespace {

using sinew::common::TetIndices;
using sinew::offline::BoundaryCheck;
using sinew::offline::BoundaryStatus;
using sinew::offline::BoundarySurface;
using sinew::offline::EmbeddedPoint;
using sinew::offline::SurfaceClosestPoint;
using sinew::offline::SurfacePoint;
using sinew::offline::SurfaceQueryStatus;
using sinew::offline::SurfaceUpdateStatus;

Eigen::VectorXd to_dofs(const Eigen::MatrixXd& positions) {
  Eigen::VectorXd x(3 * positions.rows());
  for (Eigen::Index v = 0; v < positions.rows(); ++v) x.segment<3>(3 * v) = positions.row(v);
  return x;
}

/// Σ_a w_a x_{v_a}, written out here (independent of offline/constraints/constraints.cpp).
Eigen::Vector3d embedded(const TetIndices& tets, const EmbeddedPoint& p, const Eigen::VectorXd& x) {
  Eigen::Vector3d r = Eigen::Vector3d::Zero();
  for (int a = 0; a < 4; ++a) r += p.weights(a) * x.segment<3>(3 * tets(p.tet, a));
  return r;
}

Eigen::Vector3d closest_on_segment(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                   const Eigen::Vector3d& b) {
  const double t = std::clamp((p - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
  return a + t * (b - a);
}

/// Reference closest point on a triangle by a different route than the library (Voronoi regions):
/// projection onto the plane when it falls inside, otherwise the best of the three edges.
Eigen::Vector3d reference_closest(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                  const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d n = (b - a).cross(c - a).normalized();
  const Eigen::Vector3d q = p - n.dot(p - a) * n;
  Eigen::Matrix<double, 3, 2> E;
  E << b - a, c - a;
  const Eigen::Vector2d vw = (E.transpose() * E).ldlt().solve(E.transpose() * (q - a));
  if (vw(0) >= 0.0 && vw(1) >= 0.0 && vw(0) + vw(1) <= 1.0) return q;
  Eigen::Vector3d best = closest_on_segment(p, a, b);
  for (const Eigen::Vector3d& candidate :
       {closest_on_segment(p, b, c), closest_on_segment(p, c, a)})
    if ((candidate - p).squaredNorm() < (best - p).squaredNorm()) best = candidate;
  return best;
}

struct Reference {
  double distance = std::numeric_limits<double>::infinity();
  Eigen::Vector3d point;
  bool unique_point = true;  // all faces within 1e-10 of the best distance give the same point
};

Reference brute_force(const Eigen::Vector3d& p, const Eigen::Matrix<int, Eigen::Dynamic, 3>& tris,
                      const Eigen::VectorXd& x) {
  std::vector<std::pair<double, Eigen::Vector3d>> all;
  for (Eigen::Index f = 0; f < tris.rows(); ++f) {
    const Eigen::Vector3d q =
        reference_closest(p, x.segment<3>(3 * tris(f, 0)), x.segment<3>(3 * tris(f, 1)),
                          x.segment<3>(3 * tris(f, 2)));
    all.emplace_back((q - p).norm(), q);
  }
  Reference r;
  for (const auto& [d, q] : all) {
    if (d < r.distance) {
      r.distance = d;
      r.point = q;
    }
  }
  for (const auto& [d, q] : all)
    if (d < r.distance + 1e-10 && (q - r.point).norm() > 1e-12) r.unique_point = false;
  return r;
}

sinew::testing::TetMesh single_tet() {
  sinew::testing::TetMesh mesh;
  mesh.rest_positions.resize(4, 3);
  mesh.rest_positions << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  mesh.tets.resize(1, 4);
  mesh.tets << 0, 1, 2, 3;
  return mesh;
}

/// Normal of boundary face f (corners from x), not normalised.
Eigen::Vector3d face_normal(const BoundarySurface& b, Eigen::Index f, const Eigen::VectorXd& x) {
  return (b.corner(f, 1, x) - b.corner(f, 0, x)).cross(b.corner(f, 2, x) - b.corner(f, 0, x));
}

TEST(BoundarySurface, SingleTetHasFourOutwardFaces) {
  const auto mesh = single_tet();
  const Eigen::VectorXd x = to_dofs(mesh.rest_positions);
  const auto boundary = BoundarySurface::extract(4, mesh.tets);
  ASSERT_TRUE(boundary);
  ASSERT_EQ(boundary->num_faces(), 4);
  EXPECT_EQ(boundary->vertices(), (std::vector<int>{0, 1, 2, 3}));
  const Eigen::Vector3d centroid = mesh.rest_positions.colwise().mean();
  std::vector<int> opposite;
  for (Eigen::Index f = 0; f < 4; ++f) {
    const auto& face = boundary->face(f);
    EXPECT_EQ(face.tet, 0);
    opposite.push_back(face.opposite_slot);
    const Eigen::Vector3d face_centroid =
        (boundary->corner(f, 0, x) + boundary->corner(f, 1, x) + boundary->corner(f, 2, x)) / 3.0;
    EXPECT_GT(face_normal(*boundary, f, x).dot(face_centroid - centroid), 0.0) << "face " << f;
    for (int i = 0; i < 3; ++i) {
      EXPECT_EQ(boundary->triangles()(f, i), face.vertices[static_cast<std::size_t>(i)]);
      EXPECT_EQ(mesh.tets(0, face.slots[static_cast<std::size_t>(i)]),
                face.vertices[static_cast<std::size_t>(i)]);
      EXPECT_NE(face.slots[static_cast<std::size_t>(i)], face.opposite_slot);
    }
    // A point of the face embeds with weight 0 at the opposite vertex and reproduces itself.
    const Eigen::Vector3d bary(0.2, 0.3, 0.5);
    const EmbeddedPoint p = boundary->embed(f, bary);
    EXPECT_EQ(p.weights(face.opposite_slot), 0.0);
    EXPECT_NEAR(p.weights.sum(), 1.0, 1e-15);
    const Eigen::Vector3d expected = 0.2 * boundary->corner(f, 0, x) +
                                     0.3 * boundary->corner(f, 1, x) +
                                     0.5 * boundary->corner(f, 2, x);
    EXPECT_LT((embedded(mesh.tets, p, x) - expected).norm(), 1e-15);
  }
  std::sort(opposite.begin(), opposite.end());
  EXPECT_EQ(opposite, (std::vector<int>{0, 1, 2, 3}));
}

TEST(BoundarySurface, BoxBoundaryIsItsSixSidesOutward) {
  const auto mesh = sinew::testing::make_box_mesh(3, 2, 4, 0.25);
  const Eigen::VectorXd x = to_dofs(mesh.rest_positions);
  const auto boundary = BoundarySurface::extract(mesh.rest_positions.rows(), mesh.tets);
  ASSERT_TRUE(boundary);
  // Two triangles per boundary square: 2·(3·2 + 2·4 + 3·4)·2.
  EXPECT_EQ(boundary->num_faces(), 2 * 2 * (3 * 2 + 2 * 4 + 3 * 4));
  const Eigen::Vector3d center(0.375, 0.25, 0.5);
  double area = 0.0;
  for (Eigen::Index f = 0; f < boundary->num_faces(); ++f) {
    const Eigen::Vector3d n = face_normal(*boundary, f, x);
    area += 0.5 * n.norm();
    const Eigen::Vector3d c =
        (boundary->corner(f, 0, x) + boundary->corner(f, 1, x) + boundary->corner(f, 2, x)) / 3.0;
    EXPECT_GT(n.dot(c - center), 0.0) << "face " << f;
  }
  EXPECT_NEAR(area, 2.0 * (0.75 * 0.5 + 0.5 * 1.0 + 0.75 * 1.0), 1e-12);
  // Interior vertices are not on the boundary: (4·3·5) − (2·1·3).
  EXPECT_EQ(boundary->vertices().size(), 4u * 3u * 5u - 2u * 1u * 3u);
}

TEST(BoundarySurface, RejectsInvalidMeshes) {
  BoundaryCheck check;
  TetIndices tets(1, 4);
  tets << 0, 1, 2, 4;
  EXPECT_FALSE(BoundarySurface::extract(4, tets, &check));
  EXPECT_EQ(check.status, BoundaryStatus::kInvalidMesh);
  EXPECT_EQ(check.tet, 0);
  tets << 0, 1, 2, 2;
  EXPECT_FALSE(BoundarySurface::extract(4, tets, &check));
  EXPECT_EQ(check.status, BoundaryStatus::kRepeatedVertex);
  EXPECT_FALSE(BoundarySurface::extract(4, TetIndices(0, 4), &check));
  EXPECT_EQ(check.status, BoundaryStatus::kEmpty);
  // Three tets on the face (0, 1, 2).
  TetIndices fan(3, 4);
  fan << 0, 1, 2, 3, 0, 2, 1, 4, 0, 1, 2, 5;
  EXPECT_FALSE(BoundarySurface::extract(6, fan, &check));
  EXPECT_EQ(check.status, BoundaryStatus::kNonManifold);
  EXPECT_NE(check.message().find("more than two tets"), std::string::npos) << check.message();
}

/// Random query points in and around the box: inside, near the surface and far away.
Eigen::MatrixXd random_points(int n, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-0.5, 1.5);
  Eigen::MatrixXd p(n, 3);
  for (int i = 0; i < n; ++i) p.row(i) << u(rng), u(rng), u(rng);
  p.row(0) << 0.5, 0.4, 0.55;   // inside
  p.row(1) << 10.0, -3.0, 2.0;  // far outside
  return p;
}

void expect_matches_brute_force(const SurfaceClosestPoint& scp, const Eigen::VectorXd& x,
                                const Eigen::MatrixXd& points) {
  const auto& tris = scp.boundary().triangles();
  std::vector<SurfacePoint> answers;
  scp.query(points, &answers);
  ASSERT_EQ(answers.size(), static_cast<std::size_t>(points.rows()));
  int unique = 0;
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    const Eigen::Vector3d p = points.row(i).transpose();
    const SurfacePoint& r = answers[static_cast<std::size_t>(i)];
    ASSERT_TRUE(r.ok()) << to_string(r.status);
    const Reference ref = brute_force(p, tris, x);
    EXPECT_NEAR(r.distance, ref.distance, 1e-12) << "query " << i;
    EXPECT_NEAR((r.point - p).norm(), r.distance, 1e-14);
    if (ref.unique_point) {
      ++unique;
      EXPECT_LT((r.point - ref.point).norm(), 1e-12) << "query " << i;
    }
    // The frozen material point reproduces the closest point through its tet's vertices.
    EXPECT_EQ(r.embedded.tet, scp.boundary().face(r.face).tet);
    EXPECT_LT((embedded(scp.tets(), r.embedded, x) - r.point).norm(), 1e-12) << "query " << i;
    EXPECT_NEAR(r.embedded.weights.sum(), 1.0, 1e-14);
    EXPECT_GE(r.embedded.weights.minCoeff(), 0.0);
    EXPECT_EQ(r.embedded.weights(scp.boundary().face(r.face).opposite_slot), 0.0);
    // Single and batch queries agree.
    const SurfacePoint single = scp.query(p);
    EXPECT_EQ(single.face, r.face);
    EXPECT_EQ(single.point, r.point);
  }
  EXPECT_GT(unique, points.rows() / 2);  // the point comparison did run
}

TEST(SurfaceClosestPoint, MatchesBruteForceOnBoxMesh) {
  const auto mesh = sinew::testing::make_box_mesh(4, 4, 4, 0.25);
  const Eigen::VectorXd x = to_dofs(mesh.rest_positions);
  auto scp = SurfaceClosestPoint::create(mesh.rest_positions.rows(), mesh.tets);
  ASSERT_TRUE(scp);
  ASSERT_EQ(scp->update(x), SurfaceUpdateStatus::kOk);
  std::mt19937 rng(7);
  expect_matches_brute_force(*scp, x, random_points(300, rng));
  // A point inside the box: closest point on the nearest side, distance to that side.
  const SurfacePoint r = scp->query(Eigen::Vector3d(0.5, 0.4, 0.9));
  EXPECT_NEAR(r.distance, 0.1, 1e-14);
  EXPECT_LT((r.point - Eigen::Vector3d(0.5, 0.4, 1.0)).norm(), 1e-14);
}

TEST(SurfaceClosestPoint, UpdateFollowsTheDeformation) {
  const auto mesh = sinew::testing::make_box_mesh(4, 4, 4, 0.25);
  const Eigen::VectorXd rest = to_dofs(mesh.rest_positions);
  auto scp = SurfaceClosestPoint::create(mesh.rest_positions.rows(), mesh.tets);
  ASSERT_TRUE(scp);
  ASSERT_EQ(scp->update(rest), SurfaceUpdateStatus::kOk);
  const Eigen::Vector3d probe(0.5, 0.5, 1.3);
  const SurfacePoint before = scp->query(probe);
  EXPECT_NEAR(before.distance, 0.3, 1e-14);

  // Smooth non-affine deformation: bend, twist and stretch (the boundary triangles change shape).
  Eigen::VectorXd x = rest;
  for (Eigen::Index v = 0; v < mesh.rest_positions.rows(); ++v) {
    const Eigen::Vector3d X = mesh.rest_positions.row(v);
    x.segment<3>(3 * v) << X(0) + 0.1 * std::sin(3.0 * X(2)), X(1) + 0.15 * X(0) * X(2),
        1.2 * X(2) + 0.1 * X(0) * X(0);
  }
  ASSERT_EQ(scp->update(x), SurfaceUpdateStatus::kOk);
  const SurfacePoint after = scp->query(probe);
  EXPECT_GT(std::abs(after.distance - before.distance), 0.05);  // the top moved up by ~0.2
  std::mt19937 rng(11);
  expect_matches_brute_force(*scp, x, random_points(200, rng));

  // Back to rest: the same answer as before.
  ASSERT_EQ(scp->update(rest), SurfaceUpdateStatus::kOk);
  EXPECT_EQ(scp->query(probe).point, before.point);
}

TEST(SurfaceClosestPoint, ReportsFailures) {
  const auto mesh = sinew::testing::make_box_mesh(1, 1, 1);
  BoundaryCheck check;
  EXPECT_FALSE(SurfaceClosestPoint::create(3, mesh.tets, &check));
  EXPECT_EQ(check.status, BoundaryStatus::kInvalidMesh);

  auto scp = SurfaceClosestPoint::create(mesh.rest_positions.rows(), mesh.tets);
  ASSERT_TRUE(scp);
  EXPECT_FALSE(scp->updated());
  EXPECT_EQ(scp->query(Eigen::Vector3d::Zero()).status, SurfaceQueryStatus::kNotUpdated);
  Eigen::VectorXd x = to_dofs(mesh.rest_positions);
  EXPECT_EQ(scp->update(x.head(x.size() - 1)), SurfaceUpdateStatus::kWrongSize);
  ASSERT_EQ(scp->update(x), SurfaceUpdateStatus::kOk);
  EXPECT_TRUE(scp->query(Eigen::Vector3d(2, 2, 2)).ok());
  EXPECT_EQ(scp->query(Eigen::Vector3d(std::nan(""), 0, 0)).status, SurfaceQueryStatus::kNonFinite);
  std::vector<SurfacePoint> out;
  scp->query(Eigen::MatrixXd::Zero(2, 2), &out);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[0].status, SurfaceQueryStatus::kWrongShape);
  // A failed update discards the previous positions.
  x(4) = std::numeric_limits<double>::infinity();
  EXPECT_EQ(scp->update(x), SurfaceUpdateStatus::kNonFinite);
  EXPECT_EQ(scp->query(Eigen::Vector3d::Zero()).status, SurfaceQueryStatus::kNotUpdated);
  // Moving keeps it working.
  SurfaceClosestPoint moved = std::move(*scp);
  ASSERT_EQ(moved.update(to_dofs(mesh.rest_positions)), SurfaceUpdateStatus::kOk);
  EXPECT_NEAR(moved.query(Eigen::Vector3d(0.5, 0.5, 3.0)).distance, 2.0, 1e-14);
}

TEST(ClosestPointOnTriangle, RegionsAndDegenerateTriangle) {
  const Eigen::Vector3d a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  using sinew::offline::closest_point_on_triangle;
  auto r = closest_point_on_triangle(Eigen::Vector3d(0.2, 0.3, 0.7), a, b, c);  // face
  EXPECT_LT((r.point - Eigen::Vector3d(0.2, 0.3, 0)).norm(), 1e-15);
  EXPECT_LT((r.barycentric - Eigen::Vector3d(0.5, 0.2, 0.3)).norm(), 1e-15);
  r = closest_point_on_triangle(Eigen::Vector3d(-1, -1, 1), a, b, c);  // vertex a
  EXPECT_EQ(r.barycentric, Eigen::Vector3d(1, 0, 0));
  r = closest_point_on_triangle(Eigen::Vector3d(1, 1, 0), a, b, c);  // edge bc
  EXPECT_LT((r.point - Eigen::Vector3d(0.5, 0.5, 0)).norm(), 1e-15);
  EXPECT_LT((r.barycentric - Eigen::Vector3d(0, 0.5, 0.5)).norm(), 1e-15);
  // Collinear corners: the closest point on the segments, with valid weights.
  r = closest_point_on_triangle(Eigen::Vector3d(0.5, 1, 0), a, b, Eigen::Vector3d(2, 0, 0));
  EXPECT_LT((r.point - Eigen::Vector3d(0.5, 0, 0)).norm(), 1e-15);
  EXPECT_NEAR(r.barycentric.sum(), 1.0, 1e-15);
  EXPECT_TRUE(r.barycentric.allFinite());
}

}  // namespace
