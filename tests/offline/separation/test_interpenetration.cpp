// Tests of offline/interpenetration (seed 003 §4.1.4): two registered organs that overlap are
// pushed apart by a FEM contact solve on small regions around the collision, everything else
// staying exactly where it was.
#include "offline/separation/interpenetration.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <vector>

#include "common/fem/tet4.hpp"
#include "offline/constraints/constraints.hpp"
#include "offline/io/tet_mesh_io.hpp"
#include "tests/support/offline_fixtures.hpp"

namespace {

using sinew::offline::InterpenetrationOptions;
using sinew::offline::InterpenetrationStatus;
using sinew::offline::InterpenetrationSummary;
using sinew::offline::TetMesh;
using sinew::testing::offline_box_mesh;

/// Boundary vertices of `mesh` inside `other`, by a brute-force point-in-tet test independent of
/// the module's detection (its own locator on the other's current positions, no bounding-box
/// pre-filter, no surface queries).
int vertices_inside(const TetMesh& mesh, const TetMesh& other) {
  // Boundary vertices: those on a face of exactly one tet (counted by brute force over faces).
  std::vector<char> on_boundary(static_cast<std::size_t>(mesh.vertices.rows()), 0);
  std::vector<std::array<int, 3>> faces;
  for (Eigen::Index t = 0; t < mesh.tets.rows(); ++t) {
    for (int skip = 0; skip < 4; ++skip) {
      std::array<int, 3> f{};
      int k = 0;
      for (int a = 0; a < 4; ++a)
        if (a != skip) f[static_cast<std::size_t>(k++)] = mesh.tets(t, a);
      std::sort(f.begin(), f.end());
      faces.push_back(f);
    }
  }
  std::sort(faces.begin(), faces.end());
  for (std::size_t i = 0; i < faces.size(); ++i) {
    const bool shared =
        (i + 1 < faces.size() && faces[i + 1] == faces[i]) || (i > 0 && faces[i - 1] == faces[i]);
    if (!shared)
      for (const int v : faces[i]) on_boundary[static_cast<std::size_t>(v)] = 1;
  }
  const Eigen::MatrixXd positions = other.vertices;
  const auto locator = sinew::offline::TetPointLocator::create(positions, other.tets);
  EXPECT_TRUE(locator.has_value());
  int inside = 0;
  for (Eigen::Index v = 0; v < mesh.vertices.rows(); ++v) {
    if (on_boundary[static_cast<std::size_t>(v)] == 0) continue;
    if (locator->locate(mesh.vertices.row(v).transpose()).status ==
        sinew::offline::EmbeddingStatus::kInside)
      ++inside;
  }
  return inside;
}

int inverted_tets(const TetMesh& mesh) {
  int inverted = 0;
  for (Eigen::Index t = 0; t < mesh.tets.rows(); ++t) {
    sinew::common::Matrix3x4d X;
    for (int k = 0; k < 4; ++k) X.col(k) = mesh.vertices.row(mesh.tets(t, k)).transpose();
    if (!(sinew::common::signed_volume(X) > 0.0)) ++inverted;
  }
  return inverted;
}

/// Vertices that moved at all, and whether each of them lies within `radius` of a vertex that was
/// penetrating (the active region is local).
struct Motion {
  int moved = 0;
  double max_displacement = 0.0;
};

Motion motion(const TetMesh& before, const TetMesh& after) {
  Motion m;
  for (Eigen::Index v = 0; v < before.vertices.rows(); ++v) {
    if (before.vertices.row(v) != after.vertices.row(v)) ++m.moved;
    m.max_displacement =
        std::max(m.max_displacement, (before.vertices.row(v) - after.vertices.row(v)).norm());
  }
  return m;
}

/// The common checks of a separated pair.
void expect_separated(const TetMesh& a0, const TetMesh& b0, const TetMesh& a, const TetMesh& b,
                      const InterpenetrationSummary& s, double overlap) {
  EXPECT_EQ(s.status, InterpenetrationStatus::kSeparated) << s.brief_report();
  EXPECT_TRUE(s.converged());
  EXPECT_GT(s.penetrating_a_before + s.penetrating_b_before, 0);
  EXPECT_EQ(s.penetrating_a_after, 0);
  EXPECT_EQ(s.penetrating_b_after, 0);
  EXPECT_EQ(s.max_depth_after, 0.0);
  // Independent check: no boundary vertex of either mesh inside the other.
  EXPECT_EQ(vertices_inside(a, b), 0);
  EXPECT_EQ(vertices_inside(b, a), 0);
  EXPECT_EQ(inverted_tets(a), 0);
  EXPECT_EQ(inverted_tets(b), 0);
  // Local: the active region is a small part of each mesh, and nothing else moved.
  EXPECT_GT(s.active_tets_a, 0);
  EXPECT_GT(s.active_tets_b, 0);
  EXPECT_LT(s.active_tets_a, a.tets.rows() / 2);
  EXPECT_LT(s.active_tets_b, b.tets.rows() / 2);
  const Motion ma = motion(a0, a), mb = motion(b0, b);
  EXPECT_EQ(ma.moved + mb.moved, s.vertices_moved);
  EXPECT_GT(ma.moved, 0);
  EXPECT_GT(mb.moved, 0);
  // Displacements of the order of the overlap, not far more.
  const double max_displacement = std::max(ma.max_displacement, mb.max_displacement);
  EXPECT_DOUBLE_EQ(max_displacement, s.max_displacement);
  EXPECT_GT(max_displacement, 0.3 * overlap);
  EXPECT_LT(max_displacement, 1.5 * overlap);
}

/// Every vertex none of whose tets is within `distance` of the contact plane x = x_contact keeps
/// its input bits (the region is a few rings of tets, never the far end of the organ).
void expect_far_vertices_fixed(const TetMesh& before, const TetMesh& after, double x_contact,
                               double distance) {
  int far = 0;
  for (Eigen::Index v = 0; v < before.vertices.rows(); ++v) {
    if (std::abs(before.vertices(v, 0) - x_contact) < distance) continue;
    ++far;
    EXPECT_EQ(before.vertices.row(v), after.vertices.row(v)) << "vertex " << v;
  }
  EXPECT_GT(far, before.vertices.rows() / 3);
}

// A is [0, 1.2] x [0, 0.5]^2; B's left face at x = 1.155 overlaps A's right end by 0.045 (9% of
// A's width) and B's cross-section [-0.15, 0.55]^2 contains A's, its grid half a cell off A's so
// that no faces are coplanar.
TEST(Interpenetration, OverlappingBoxesAreSeparatedLocally) {
  const double overlap = 0.045;
  TetMesh a = offline_box_mesh(12, 5, 5, 0.1, {0.0, 0.0, 0.0});
  TetMesh b = offline_box_mesh(12, 7, 7, 0.1, {1.2 - overlap, -0.15, -0.15});
  const TetMesh a0 = a, b0 = b;

  const auto before_a = sinew::offline::find_penetrations(a, b);
  const auto before_b = sinew::offline::find_penetrations(b, a);
  ASSERT_TRUE(before_a && before_b);
  EXPECT_EQ(before_a->vertices.size(), 36);  // A's right end face, 6 x 6 vertices
  EXPECT_EQ(before_b->vertices.size(), 25);  // B's left-face vertices within A's section
  EXPECT_NEAR(before_a->max_depth(), overlap, 1e-12);
  EXPECT_EQ(vertices_inside(a, b), 36);
  EXPECT_EQ(vertices_inside(b, a), 25);

  const InterpenetrationSummary s = sinew::offline::remove_interpenetration(a, b);
  std::cout << s.brief_report() << "\n";
  EXPECT_EQ(s.penetrating_a_before, 36);
  EXPECT_EQ(s.penetrating_b_before, 25);
  EXPECT_NEAR(s.max_depth_before, overlap, 1e-12);
  expect_separated(a0, b0, a, b, s, overlap);
  expect_far_vertices_fixed(a0, a, 1.2, 0.45);
  expect_far_vertices_fixed(b0, b, 1.2 - overlap, 0.45);
  // The ends were pushed apart along x: A's end moved back, B's face forward.
  EXPECT_LT(a.vertices.col(0).maxCoeff(), 1.2 - 0.25 * overlap);
  double b_face = 1e9;  // smallest x of B's vertices within A's cross-section
  for (Eigen::Index v = 0; v < b.vertices.rows(); ++v) {
    if (b.vertices(v, 1) > 0 && b.vertices(v, 1) < 0.5 && b.vertices(v, 2) > 0 &&
        b.vertices(v, 2) < 0.5)
      b_face = std::min(b_face, b.vertices(v, 0));
  }
  EXPECT_GT(b_face, 1.2 - 0.75 * overlap);
}

// A tilted bar whose lowest corner dips 0.04 into the top face of a larger slab: an oblique contact
// on a corner, where the slab's side of the contact has few or no vertices inside the bar.
TEST(Interpenetration, RotatedBoxCornerIsPushedOutOfSlab) {
  TetMesh slab = offline_box_mesh(12, 12, 3, 0.1, {-0.6, -0.6, -0.3});  // top face z = 0
  TetMesh bar = offline_box_mesh(3, 3, 6, 0.1, {-0.15, -0.15, 0.0});
  // Tilt the bar 30 degrees about x and 20 about y around its base centre, then lower it so that
  // its lowest corner is 0.04 below the slab's top face.
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(0.35, Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(0.52, Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  bar.vertices = (bar.vertices * R.transpose()).eval();
  const double depth = 0.04;
  bar.vertices.col(2).array() -= bar.vertices.col(2).minCoeff() + depth;
  const TetMesh slab0 = slab, bar0 = bar;
  ASSERT_GT(vertices_inside(bar, slab), 0);

  const InterpenetrationSummary s = sinew::offline::remove_interpenetration(bar, slab);
  std::cout << s.brief_report() << "\n";
  expect_separated(bar0, slab0, bar, slab, s, depth);
  EXPECT_NEAR(s.max_depth_before, depth, 1e-9);
  // Both sides gave way: the corner rose, the slab's face was dented, by less than the depth.
  Eigen::Index corner = 0;
  bar0.vertices.col(2).minCoeff(&corner);
  EXPECT_GT(bar.vertices(corner, 2), bar0.vertices(corner, 2) + 0.25 * depth);
  EXPECT_GT(bar.vertices.col(2).minCoeff(), -0.75 * depth);
  // The slab away from the contact (and its bottom) stays put, bit for bit.
  const Eigen::Vector2d contact = bar0.vertices.row(corner).head<2>().transpose();
  int far = 0;
  for (Eigen::Index v = 0; v < slab.vertices.rows(); ++v) {
    if (slab0.vertices(v, 2) < -0.25 ||
        (slab0.vertices.row(v).head<2>().transpose() - contact).norm() > 0.45) {
      ++far;
      EXPECT_EQ(slab0.vertices.row(v), slab.vertices.row(v));
    }
  }
  EXPECT_GT(far, slab.vertices.rows() / 2);
}

// Curved contact: the torus of ../shared/data/libpgo_models (tube radius ~0.1, ring radius ~0.2,
// axis x) and a copy moved 0.57 along y, their outer rims overlapping by ~0.024.
TEST(Interpenetration, OverlappingToriAreSeparated) {
  const std::string path = SINEW_SHARED_DIR "/data/libpgo_models/torus.veg";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "not found: " << path;
  const auto read = sinew::offline::read_tet_mesh(path);
  ASSERT_TRUE(read.ok()) << read.error;
  TetMesh a = *read.mesh, b = *read.mesh;
  b.vertices.col(1).array() += 0.57;
  const TetMesh a0 = a, b0 = b;
  ASSERT_GT(vertices_inside(a, b) + vertices_inside(b, a), 0);

  const InterpenetrationSummary s = sinew::offline::remove_interpenetration(a, b);
  std::cout << s.brief_report() << "\n";
  expect_separated(a0, b0, a, b, s, s.max_depth_before);
  EXPECT_GT(s.max_depth_before, 0.01);
  // The tori are mirror images across y = 0.285 up to the mesh's own asymmetry: each gives way
  // by a similar amount (neither side does all the work).
  const Motion ma = motion(a0, a), mb = motion(b0, b);
  EXPECT_GT(ma.max_displacement, 0.25 * s.max_depth_before);
  EXPECT_GT(mb.max_displacement, 0.25 * s.max_depth_before);
  // The far halves (y < 0 for A, y > 0.57 for B) do not move.
  for (Eigen::Index v = 0; v < a0.vertices.rows(); ++v) {
    if (a0.vertices(v, 1) < 0.0) {
      EXPECT_EQ(a0.vertices.row(v), a.vertices.row(v));
    }
    if (b0.vertices(v, 1) > 0.57) {
      EXPECT_EQ(b0.vertices.row(v), b.vertices.row(v));
    }
  }
}

TEST(Interpenetration, SeparatePairIsReturnedUnchanged) {
  TetMesh a = offline_box_mesh(3, 3, 3, 0.1, {0.0, 0.0, 0.0});
  TetMesh b = offline_box_mesh(3, 3, 3, 0.1, {0.31, 0.0, 0.0});
  const TetMesh a0 = a, b0 = b;
  const InterpenetrationSummary s = sinew::offline::remove_interpenetration(a, b);
  std::cout << s.brief_report() << "\n";
  EXPECT_EQ(s.status, InterpenetrationStatus::kNoContact) << s.message;
  EXPECT_TRUE(s.converged());
  EXPECT_EQ(s.penetrating_a_before, 0);
  EXPECT_EQ(s.penetrating_b_before, 0);
  EXPECT_EQ(s.vertices_moved, 0);
  EXPECT_EQ(s.max_displacement, 0.0);
  EXPECT_EQ(a.vertices, a0.vertices);
  EXPECT_EQ(b.vertices, b0.vertices);
}

TEST(Interpenetration, InvalidOptionsAndMeshesAreReported) {
  TetMesh a = offline_box_mesh(2, 2, 2, 0.1, {0.0, 0.0, 0.0});
  TetMesh b = offline_box_mesh(2, 2, 2, 0.1, {0.15, 0.0, 0.0});
  const TetMesh a0 = a, b0 = b;
  InterpenetrationOptions options;
  options.ring_size = -1;
  EXPECT_EQ(options.validate().value_or(""),
            "InterpenetrationOptions::ring_size = -1 must be >= 0");
  InterpenetrationSummary s = sinew::offline::remove_interpenetration(a, b, options);
  EXPECT_EQ(s.status, InterpenetrationStatus::kInvalidInput);
  EXPECT_EQ(s.message, *options.validate());
  EXPECT_FALSE(s.converged());

  options = {};
  options.contact_margin = 1.5;
  EXPECT_EQ(options.validate().value_or(""),
            "InterpenetrationOptions::contact_margin = 1.5 must be in [0, 1)");
  options = {};
  options.penalty_stiffness = 0.0;
  EXPECT_EQ(options.validate().value_or(""),
            "InterpenetrationOptions::penalty_stiffness = 0 must be finite and > 0");
  options = {};
  options.max_iterations = 0;
  EXPECT_EQ(options.validate().value_or(""),
            "InterpenetrationOptions::max_iterations = 0 must be >= 1");
  options = {};
  options.material.poisson_ratio = 0.5;
  EXPECT_EQ(options.validate().value_or(""),
            "InterpenetrationOptions::material.poisson_ratio = 0.5 must be in (-1, 0.5)");
  EXPECT_FALSE(InterpenetrationOptions{}.validate().has_value());

  // An inverted tet in B.
  std::swap(b.tets(3, 0), b.tets(3, 1));
  s = sinew::offline::remove_interpenetration(a, b);
  EXPECT_EQ(s.status, InterpenetrationStatus::kInvalidInput);
  EXPECT_EQ(s.message, "mesh B tet 3 is inverted or degenerate (tets must be right-handed)");
  EXPECT_EQ(a.vertices, a0.vertices);
  EXPECT_EQ(b.vertices, b0.vertices);
}

}  // namespace
