// Tests of offline/meshing/tet_mesher: CGAL Mesh_3 on closed surfaces built here (icosphere,
// cube), mesh validity and quality, approximation of the surface, determinism, and the one-line
// messages for invalid options and invalid surfaces.
#include "offline/meshing/tet_mesher.hpp"

#include <Eigen/Geometry>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <limits>
#include <map>
#include <utility>
#include <vector>

#include "common/fem/tet_mesh_elasticity.hpp"

namespace {

using sinew::offline::make_tet_mesh;
using sinew::offline::TetMesh;
using sinew::offline::TetMesherOptions;
using sinew::offline::TetMesherResult;
using sinew::offline::TetMesherStatus;

constexpr double kPi = 3.14159265358979323846;

struct Surface {
  Eigen::MatrixXd V;
  Eigen::MatrixXi F;
};

/// Unit icosphere (outward faces): the icosahedron, each face split in 4 `levels` times, vertices
/// pushed onto the sphere of the given radius.
Surface icosphere(int levels, double radius = 1.0) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Eigen::Vector3d> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0},
                                    {0, -1, t}, {0, 1, t}, {0, -1, -t}, {0, 1, -t},
                                    {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  std::vector<std::array<int, 3>> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                       {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                       {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                       {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (auto& p : v) p.normalize();
  for (int level = 0; level < levels; ++level) {
    std::map<std::pair<int, int>, int> midpoint;
    const auto mid = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      const auto it = midpoint.find(key);
      if (it != midpoint.end()) return it->second;
      v.push_back((v[static_cast<std::size_t>(a)] + v[static_cast<std::size_t>(b)]).normalized());
      return midpoint[key] = static_cast<int>(v.size()) - 1;
    };
    std::vector<std::array<int, 3>> next;
    for (const auto& [a, b, c] : f) {
      const int ab = mid(a, b), bc = mid(b, c), ca = mid(c, a);
      next.push_back({a, ab, ca});
      next.push_back({b, bc, ab});
      next.push_back({c, ca, bc});
      next.push_back({ab, bc, ca});
    }
    f = std::move(next);
  }
  Surface s;
  s.V.resize(static_cast<Eigen::Index>(v.size()), 3);
  for (std::size_t i = 0; i < v.size(); ++i)
    s.V.row(static_cast<Eigen::Index>(i)) = radius * v[i].transpose();
  s.F.resize(static_cast<Eigen::Index>(f.size()), 3);
  for (std::size_t i = 0; i < f.size(); ++i)
    for (int a = 0; a < 3; ++a)
      s.F(static_cast<Eigen::Index>(i), a) = f[i][static_cast<std::size_t>(a)];
  return s;
}

/// Axis-aligned box [0, a] x [0, b] x [0, c], two outward triangles per side.
Surface box(double a, double b, double c) {
  Surface s;
  s.V.resize(8, 3);
  for (int i = 0; i < 8; ++i) s.V.row(i) << a * (i & 1), b * ((i >> 1) & 1), c * ((i >> 2) & 1);
  s.F.resize(12, 3);
  s.F << 0, 2, 1, 1, 2, 3,  // z = 0
      4, 5, 6, 5, 7, 6,     // z = c
      0, 1, 4, 1, 5, 4,     // y = 0
      2, 6, 3, 3, 6, 7,     // y = b
      0, 4, 2, 2, 4, 6,     // x = 0
      1, 3, 5, 3, 7, 5;     // x = a
  return s;
}

double enclosed_volume(const Surface& s) {
  double six_v = 0.0;
  for (Eigen::Index f = 0; f < s.F.rows(); ++f) {
    const Eigen::Vector3d a = s.V.row(s.F(f, 0)), b = s.V.row(s.F(f, 1)), c = s.V.row(s.F(f, 2));
    six_v += a.dot(b.cross(c));
  }
  return six_v / 6.0;
}

double tet_volume(const TetMesh& m, Eigen::Index t) {
  const Eigen::Vector3d p0 = m.vertices.row(m.tets(t, 0));
  return (m.vertices.row(m.tets(t, 1)).transpose() - p0)
             .dot((m.vertices.row(m.tets(t, 2)).transpose() - p0)
                      .cross(m.vertices.row(m.tets(t, 3)).transpose() - p0)) /
         6.0;
}

/// Distance from p to triangle (a, b, c): plane projection if inside, else the nearest edge.
double point_triangle_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                               const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const auto segment = [&p](const Eigen::Vector3d& u, const Eigen::Vector3d& w) {
    const double t = std::clamp((p - u).dot(w - u) / (w - u).squaredNorm(), 0.0, 1.0);
    return (u + t * (w - u) - p).norm();
  };
  const Eigen::Vector3d n = (b - a).cross(c - a).normalized();
  const Eigen::Vector3d q = p - n.dot(p - a) * n;
  const auto inside = [&](const Eigen::Vector3d& u, const Eigen::Vector3d& w) {
    return (w - u).cross(q - u).dot(n) >= 0.0;
  };
  if (inside(a, b) && inside(b, c) && inside(c, a)) return (q - p).norm();
  return std::min({segment(a, b), segment(b, c), segment(c, a)});
}

double distance_to_surface(const Eigen::Vector3d& p, const Surface& s) {
  double d = std::numeric_limits<double>::infinity();
  for (Eigen::Index f = 0; f < s.F.rows(); ++f)
    d = std::min(
        d, point_triangle_distance(p, s.V.row(s.F(f, 0)), s.V.row(s.F(f, 1)), s.V.row(s.F(f, 2))));
  return d;
}

/// Boundary faces (sorted vertex triples of faces owned by one tet) of a tet mesh.
std::vector<std::array<int, 3>> boundary_faces(const TetMesh& m) {
  std::map<std::array<int, 3>, int> count;
  for (Eigen::Index t = 0; t < m.tets.rows(); ++t) {
    for (int skip = 0; skip < 4; ++skip) {
      std::array<int, 3> f{};
      int k = 0;
      for (int a = 0; a < 4; ++a)
        if (a != skip) f[static_cast<std::size_t>(k++)] = m.tets(t, a);
      std::sort(f.begin(), f.end());
      ++count[f];
    }
  }
  std::vector<std::array<int, 3>> boundary;
  for (const auto& [f, n] : count) {
    EXPECT_LE(n, 2);
    if (n == 1) boundary.push_back(f);
  }
  return boundary;
}

/// Smallest and largest dihedral angle (degrees), computed from face normals.
std::pair<double, double> dihedral_range(const TetMesh& m) {
  double lo = 180.0, hi = 0.0;
  for (Eigen::Index t = 0; t < m.tets.rows(); ++t) {
    std::array<Eigen::Vector3d, 4> p;
    for (int a = 0; a < 4; ++a) p[static_cast<std::size_t>(a)] = m.vertices.row(m.tets(t, a));
    // Outward normal of the face opposite vertex i; dihedral at edge (i, j) = π − angle(n_i, n_j).
    std::array<Eigen::Vector3d, 4> n;
    for (int i = 0; i < 4; ++i) {
      const auto& a = p[static_cast<std::size_t>((i + 1) % 4)];
      const auto& b = p[static_cast<std::size_t>((i + 2) % 4)];
      const auto& c = p[static_cast<std::size_t>((i + 3) % 4)];
      Eigen::Vector3d normal = (b - a).cross(c - a).normalized();
      if (normal.dot(a - p[static_cast<std::size_t>(i)]) < 0.0) normal = -normal;
      n[static_cast<std::size_t>(i)] = normal;
    }
    for (int i = 0; i < 4; ++i) {
      for (int j = i + 1; j < 4; ++j) {
        const double c = std::clamp(
            n[static_cast<std::size_t>(i)].dot(n[static_cast<std::size_t>(j)]), -1.0, 1.0);
        const double angle = 180.0 - std::acos(c) * 180.0 / kPi;
        lo = std::min(lo, angle);
        hi = std::max(hi, angle);
      }
    }
  }
  return {lo, hi};
}

TEST(TetMesher, SphereMeshIsValidAccurateAndWellShaped) {
  const Surface sphere = icosphere(3);  // 1280 faces
  const TetMesherResult r = make_tet_mesh(sphere.V, sphere.F);
  std::cout << r.summary.full_report();
  ASSERT_TRUE(r.summary.ok()) << r.summary.brief_report();
  const TetMesh& m = r.mesh;
  EXPECT_EQ(r.summary.num_tets, m.tets.rows());
  EXPECT_EQ(r.summary.num_vertices, m.vertices.rows());
  // "A few thousand tets" with the default options.
  EXPECT_GT(m.tets.rows(), 1000);
  EXPECT_LT(m.tets.rows(), 20000);

  // Right-handed, non-degenerate tets that use every vertex.
  const auto check = sinew::common::check_tet_mesh(m.vertices, m.tets);
  EXPECT_TRUE(check.ok()) << check.message();
  EXPECT_EQ(r.summary.flipped_tets, 0);  // CGAL's cells are already positively oriented
  std::vector<bool> used(static_cast<std::size_t>(m.vertices.rows()), false);
  double volume = 0.0;
  for (Eigen::Index t = 0; t < m.tets.rows(); ++t) {
    EXPECT_GT(tet_volume(m, t), 0.0) << "tet " << t;
    volume += tet_volume(m, t);
    for (int a = 0; a < 4; ++a) used[static_cast<std::size_t>(m.tets(t, a))] = true;
  }
  EXPECT_TRUE(std::all_of(used.begin(), used.end(), [](bool u) { return u; }));

  // Volume of the solid: within 2% of the volume enclosed by the input polyhedron.
  const double exact = enclosed_volume(sphere);
  EXPECT_NEAR(r.summary.enclosed_volume, exact, 1e-12 * exact);
  EXPECT_NEAR(r.summary.tet_volume, volume, 1e-9 * volume);
  EXPECT_NEAR(volume, exact, 0.02 * exact);
  std::cout << "volume error " << (volume - exact) / exact * 100.0 << " %\n";

  // Dihedral angles: the summary's range is the true range, and the smallest is sane.
  const auto [lo, hi] = dihedral_range(m);
  EXPECT_NEAR(*r.summary.min_dihedral_degrees, lo, 1e-6);
  EXPECT_NEAR(*r.summary.max_dihedral_degrees, hi, 1e-6);
  EXPECT_GT(lo, 5.0);
  EXPECT_LT(hi, 175.0);
  EXPECT_GT(*r.summary.min_radius_ratio, 0.0);
  EXPECT_GT(*r.summary.mean_radius_ratio, 0.5);

  // The boundary of the tet mesh approximates the input: its vertices lie on the surface and its
  // face centroids stay within a small fraction of the diagonal.
  const auto boundary = boundary_faces(m);
  EXPECT_EQ(static_cast<Eigen::Index>(boundary.size()), r.summary.num_boundary_faces);
  const double diagonal = r.summary.bounding_box_diagonal;
  double max_vertex = 0.0, max_centroid = 0.0;
  for (const auto& f : boundary) {
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (const int v : f) {
      const Eigen::Vector3d p = m.vertices.row(v);
      max_vertex = std::max(max_vertex, distance_to_surface(p, sphere));
      centroid += p / 3.0;
    }
    max_centroid = std::max(max_centroid, distance_to_surface(centroid, sphere));
  }
  std::cout << "max boundary vertex / centroid distance (fraction of diagonal): "
            << max_vertex / diagonal << " / " << max_centroid / diagonal << "\n";
  EXPECT_LT(max_vertex, 1e-6 * diagonal);
  EXPECT_LT(max_centroid, 0.01 * diagonal);
}

TEST(TetMesher, DeterministicForFixedSeed) {
  const Surface sphere = icosphere(2);
  TetMesherOptions options;
  options.random_seed = 42;
  options.lloyd = true;  // every phase on
  options.smoothing_iterations = 5;
  const TetMesherResult a = make_tet_mesh(sphere.V, sphere.F, options);
  const TetMesherResult b = make_tet_mesh(sphere.V, sphere.F, options);
  ASSERT_TRUE(a.summary.ok()) << a.summary.brief_report();
  ASSERT_TRUE(b.summary.ok()) << b.summary.brief_report();
  EXPECT_GT(a.mesh.tets.rows(), 500);
  EXPECT_FALSE(a.summary.time_limit_reached);
  ASSERT_EQ(a.mesh.tets.rows(), b.mesh.tets.rows());
  ASSERT_EQ(a.mesh.vertices.rows(), b.mesh.vertices.rows());
  EXPECT_TRUE(a.mesh.tets == b.mesh.tets);
  EXPECT_TRUE(a.mesh.vertices == b.mesh.vertices);  // bitwise
}

TEST(TetMesher, InwardOrientedSmallSurfaceIsMeshed) {
  Surface sphere = icosphere(2, 0.05);  // 5 cm: sizes are relative to the diagonal
  sphere.F.col(1).swap(sphere.F.col(2));
  const TetMesherResult r = make_tet_mesh(sphere.V, sphere.F);
  ASSERT_TRUE(r.summary.ok()) << r.summary.brief_report();
  EXPECT_TRUE(r.summary.input_inward_oriented);
  EXPECT_NEAR(r.summary.tet_volume, r.summary.enclosed_volume, 0.03 * r.summary.enclosed_volume);
  EXPECT_GT(*r.summary.min_dihedral_degrees, 5.0);
  EXPECT_TRUE(sinew::common::check_tet_mesh(r.mesh.vertices, r.mesh.tets).ok());
}

TEST(TetMesher, BoxWithProtectedFeaturesKeepsCornersAndVolume) {
  const Surface cube = box(1.0, 0.8, 0.6);
  TetMesherOptions options;
  options.protect_sharp_features = true;
  options.cell_size_fraction = 0.1;
  const TetMesherResult r = make_tet_mesh(cube.V, cube.F, options);
  ASSERT_TRUE(r.summary.ok()) << r.summary.brief_report();
  std::cout << r.summary.brief_report() << "\n";
  EXPECT_NEAR(r.summary.tet_volume, 0.48, 1e-6);  // planar sides and kept corners: exact
  for (Eigen::Index c = 0; c < 8; ++c) {
    const Eigen::Vector3d corner = cube.V.row(c);
    double nearest = std::numeric_limits<double>::infinity();
    for (Eigen::Index v = 0; v < r.mesh.vertices.rows(); ++v)
      nearest = std::min(nearest, (r.mesh.vertices.row(v).transpose() - corner).norm());
    EXPECT_LT(nearest, 1e-9) << "corner " << c;
  }
  EXPECT_GT(*r.summary.min_dihedral_degrees, 5.0);
}

TEST(TetMesher, InvalidOptionsNameFieldValueAndConstraint) {
  const Surface sphere = icosphere(1);
  TetMesherOptions options;
  options.cell_size_fraction = -0.5;
  TetMesherResult r = make_tet_mesh(sphere.V, sphere.F, options);
  EXPECT_EQ(r.summary.status, TetMesherStatus::kInvalidOptions);
  EXPECT_EQ(r.summary.message, "cell_size_fraction = -0.5 must be in (0, 1]");
  EXPECT_EQ(r.mesh.tets.rows(), 0);
  options = {};
  options.facet_angle_degrees = 45.0;
  ASSERT_TRUE(options.validate());
  EXPECT_NE(options.validate()->find("facet_angle_degrees = 45"), std::string::npos);
  options = {};
  options.cell_radius_edge_ratio = 1.5;
  ASSERT_TRUE(options.validate());
  EXPECT_NE(options.validate()->find("cell_radius_edge_ratio = 1.5 must be"), std::string::npos);
  options = {};
  options.smoothing_iterations = 0;
  EXPECT_TRUE(options.validate());
  EXPECT_FALSE(TetMesherOptions{}.validate());
  EXPECT_NE(r.summary.brief_report().find("invalid options"), std::string::npos);
}

TEST(TetMesher, RejectsOpenSurfaceWithClearMessage) {
  Surface sphere = icosphere(1);
  const Eigen::MatrixXi all = sphere.F;
  sphere.F = all.topRows(all.rows() - 1);  // a hole: the last triangle is missing
  const TetMesherResult r = make_tet_mesh(sphere.V, sphere.F);
  EXPECT_EQ(r.summary.status, TetMesherStatus::kOpenSurface);
  EXPECT_NE(r.summary.message.find("the surface is open: 3 edges belong to one face only"),
            std::string::npos)
      << r.summary.message;
  EXPECT_EQ(r.mesh.tets.rows(), 0);
}

TEST(TetMesher, RejectsOtherInvalidSurfaces) {
  const Surface sphere = icosphere(1);
  {  // one face flipped
    Surface s = sphere;
    std::swap(s.F(3, 1), s.F(3, 2));
    const auto r = make_tet_mesh(s.V, s.F);
    EXPECT_EQ(r.summary.status, TetMesherStatus::kNonManifoldSurface);
    EXPECT_NE(r.summary.message.find("not consistently oriented"), std::string::npos)
        << r.summary.message;
  }
  {  // index out of range
    Surface s = sphere;
    s.F(5, 0) = static_cast<int>(s.V.rows());
    const auto r = make_tet_mesh(s.V, s.F);
    EXPECT_EQ(r.summary.status, TetMesherStatus::kInvalidSurface);
    EXPECT_NE(r.summary.message.find("face 5 references vertex"), std::string::npos);
  }
  {  // non-finite vertex
    Surface s = sphere;
    s.V(2, 1) = std::nan("");
    EXPECT_EQ(make_tet_mesh(s.V, s.F).summary.status, TetMesherStatus::kInvalidSurface);
  }
  {  // two spheres touching at one vertex (pinched): the second is the point reflection of the
     // first through its vertex of largest x, and shares that vertex
    Surface s;
    const Eigen::Index n = sphere.V.rows();
    Eigen::Index right = 0;
    sphere.V.col(0).maxCoeff(&right);
    s.V.resize(2 * n, 3);
    s.V.topRows(n) = sphere.V;
    s.V.bottomRows(n) = (-sphere.V).rowwise() + 2.0 * sphere.V.row(right);
    Eigen::MatrixXi F2 = sphere.F.array() + static_cast<int>(n);
    F2.col(1).swap(F2.col(2));  // reflection flips orientation; restore outward
    for (Eigen::Index f = 0; f < F2.rows(); ++f)
      for (int a = 0; a < 3; ++a)
        if (F2(f, a) == n + right) F2(f, a) = static_cast<int>(right);  // shared vertex
    s.F.resize(2 * sphere.F.rows(), 3);
    s.F << sphere.F, F2;
    const auto r = make_tet_mesh(s.V, s.F);
    EXPECT_EQ(r.summary.status, TetMesherStatus::kNonManifoldSurface);
    EXPECT_NE(r.summary.message.find("pinched vertex"), std::string::npos) << r.summary.message;
  }
  {  // two overlapping spheres in one surface: closed and manifold, but self-intersecting
    Surface s;
    const Eigen::Index n = sphere.V.rows();
    s.V.resize(2 * n, 3);
    s.V << sphere.V, sphere.V.rowwise() + Eigen::RowVector3d(0.7, 0.1, 0.05);
    s.F.resize(2 * sphere.F.rows(), 3);
    s.F << sphere.F, sphere.F.array() + static_cast<int>(n);
    const auto r = make_tet_mesh(s.V, s.F);
    EXPECT_EQ(r.summary.status, TetMesherStatus::kSelfIntersecting);
    EXPECT_NE(r.summary.message.find("intersects itself"), std::string::npos);
    // The named pair is one face of each sphere (faces of one sphere never cross each other).
    long f = -1, g = -1;
    ASSERT_EQ(std::sscanf(r.summary.message.c_str(),
                          "the surface intersects itself: faces %ld and %ld cross", &f, &g),
              2)
        << r.summary.message;
    EXPECT_LT(f, sphere.F.rows()) << r.summary.message;
    EXPECT_GE(g, sphere.F.rows()) << r.summary.message;
    EXPECT_LT(g, 2 * sphere.F.rows()) << r.summary.message;
  }
}

TEST(TetMesher, VertexLimitIsReported) {
  const Surface sphere = icosphere(2);
  TetMesherOptions options;
  options.max_vertices = 50;
  const auto r = make_tet_mesh(sphere.V, sphere.F, options);
  EXPECT_EQ(r.summary.status, TetMesherStatus::kVertexLimitReached);
  EXPECT_NE(r.summary.message.find("max_vertices = 50"), std::string::npos) << r.summary.message;
}

}  // namespace

namespace {

// Per tet of a mesh of the slab 0 ≤ z ≤ thickness: its extent in z over the thickness (1: the tet
// spans the slab, one tet across; 1/3: three across).
std::vector<double> z_extents(const TetMesh& mesh, double thickness) {
  std::vector<double> extents;
  for (Eigen::Index t = 0; t < mesh.tets.rows(); ++t) {
    double low = std::numeric_limits<double>::infinity(), high = -low;
    for (int a = 0; a < 4; ++a) {
      const double z = mesh.vertices(mesh.tets(t, a), 2);
      low = std::min(low, z);
      high = std::max(high, z);
    }
    extents.push_back((high - low) / thickness);
  }
  return extents;
}

double median(std::vector<double> values) {
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

}  // namespace

TEST(TetMesher, ThicknessSizedCellsPutSeveralTetsAcrossAThinSlab) {
  // A 0.5 x 0.5 x 0.04 slab: the uniform bound (0.15 of the diagonal, 0.11) puts one tet across;
  // sized from the thickness (the chord along the inward normal, 0.04) the tets are
  // thickness / 3 in circumradius, so a tet spans about a third to a half of the slab.
  const double thickness = 0.04;
  const Surface slab = box(0.5, 0.5, thickness);
  TetMesherOptions options;
  options.cell_size_fraction = 0.15;
  options.protect_sharp_features = true;
  const TetMesherResult uniform = make_tet_mesh(slab.V, slab.F, options);
  ASSERT_TRUE(uniform.summary.ok()) << uniform.summary.brief_report();
  options.tets_across_thickness = 3.0;
  const TetMesherResult sized = make_tet_mesh(slab.V, slab.F, options);
  ASSERT_TRUE(sized.summary.ok()) << sized.summary.brief_report();
  const double uniform_median = median(z_extents(uniform.mesh, thickness));
  const double sized_median = median(z_extents(sized.mesh, thickness));
  std::cout << "slab: uniform " << uniform.summary.num_tets << " tets, median z extent "
            << uniform_median << " of the thickness; thickness-sized " << sized.summary.num_tets
            << " tets, " << sized_median << "\n";
  EXPECT_GT(uniform_median, 0.9);
  EXPECT_LT(sized_median, 0.6);
  EXPECT_GT(sized.summary.num_tets, uniform.summary.num_tets);
  EXPECT_NEAR(sized.summary.tet_volume, 0.25 * thickness, 1e-6);
  EXPECT_TRUE(sinew::common::check_tet_mesh(sized.mesh.vertices, sized.mesh.tets).ok());

  // thin_fraction_of_median (issue 51): the slab's median thickness is its own (the two large
  // faces are most of the area), so at half the median nothing is thin and the mesh is the
  // uniform one; at twice the median the slab is thin and sized as above.
  options.thin_fraction_of_median = 0.5;
  const TetMesherResult none_thin = make_tet_mesh(slab.V, slab.F, options);
  ASSERT_TRUE(none_thin.summary.ok()) << none_thin.summary.brief_report();
  EXPECT_EQ(none_thin.summary.num_tets, uniform.summary.num_tets);
  EXPECT_GT(median(z_extents(none_thin.mesh, thickness)), 0.9);
  options.thin_fraction_of_median = 2.0;
  const TetMesherResult all_thin = make_tet_mesh(slab.V, slab.F, options);
  ASSERT_TRUE(all_thin.summary.ok()) << all_thin.summary.brief_report();
  EXPECT_EQ(all_thin.summary.num_tets, sized.summary.num_tets);
  EXPECT_LT(median(z_extents(all_thin.mesh, thickness)), 0.6);
  options.thin_fraction_of_median = -1.0;
  EXPECT_TRUE(options.validate().has_value());
}
