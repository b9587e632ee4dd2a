// The paper's qualitative figures as measured tests (seed 003).
// (a) Fig. 4: a 12x3x3-cube beam whose end faces are attached along their y-centre lines on an
// arc (the attachments BEND it and carry no y information) and whose 24 ICP markers (15% of the
// surface vertices) lie on the bent beam stretched 2x in y. Recovered as sinew-register runs it
// (10 point-to-plane ICP iterations first): markers met to 0.7 µm, middle cross-section 2.006x
// wide in y and 1.003x in z, Fp in the middle third with mean principal stretches 2.00 along y and
// 1.03 across, the surface within 0.95% of the diagonal of the target. Material still slides along
// the axis (see the comments). A finer mesh with markers on the sides only is checked too.
// (b) Fig. 2: the "FEM static" baseline (the template deformed purely elastically, s = identity,
// under a stiff point spring) makes a spike at the constrained point (ratio 5.1), while the
// plastic-strain registration with the same point as a landmark spreads it (ratio 1.14); ratio =
// displacement of the constrained vertex over the mean displacement of the vertices within two
// element lengths of it.

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <iostream>
#include <optional>
#include <random>
#include <vector>

#include "offline/constraints/constraints.hpp"
#include "offline/equilibrium/equilibrium.hpp"
#include "offline/meshing/surface_closest_point.hpp"
#include "offline/plastic/plastic_elastic_energy.hpp"
#include "offline/plastic/plastic_strain.hpp"
#include "offline/registration/gauss_newton.hpp"
#include "tests/support/offline_fixtures.hpp"
#include "tests/support/tet_mesh_fixtures.hpp"

namespace sinew::offline {
namespace {

using testing::at_vertex;
using testing::soft_tissue;

// Vertex (i, j, k) of testing::make_box_mesh(nx, ny, nz, h).
struct BoxGrid {
  int nx, ny, nz;
  int operator()(int i, int j, int k) const { return i + (nx + 1) * (j + (ny + 1) * k); }
};

Eigen::Vector3d rest_vertex(const testing::TetMesh& mesh, int v) {
  return mesh.rest_positions.row(v).transpose();
}

Eigen::Vector3d tet_centroid(const testing::TetMesh& mesh, Eigen::Index t) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (int a = 0; a < 4; ++a) c += rest_vertex(mesh, mesh.tets(t, a)) / 4;
  return c;
}

// ---------------------------------------------------------------------------------------------
// Fig. 4: bend (attachments) + 2x transverse stretch (ICP markers).

// The target shape, analytically: the rest beam [0, L] x [0, W] x [0, W] stretched by y_stretch
// in y about its axis, then bent in the x-z plane onto an arc of the given total angle (the
// centre line keeps its length; the middle section stays in place, the ends rise and turn by
// ±angle/2).
struct BendStretch {
  double length = 0.0;
  double angle = 0.0;  // radians, total
  double y_centre = 0.0;
  double z_centre = 0.0;
  double y_stretch = 1.0;

  double radius() const { return length / angle; }
  Eigen::Vector3d operator()(const Eigen::Vector3d& X) const {
    const double R = radius();
    const double phi = (X.x() - length / 2) / R;
    const double dz = X.z() - z_centre;
    return {length / 2 + (R - dz) * std::sin(phi), y_centre + y_stretch * (X.y() - y_centre),
            z_centre + R - (R - dz) * std::cos(phi)};
  }
};

// The Fig. 4 case on the beam of 12x3x3 cubes of 2.5 cm (0.3 x 0.075 x 0.075 m, 648 tets) refined
// `refine` times per axis, registered with `options`; checks the recovery against the target
// (shape within shape_tolerance of the diagonal) and returns the run's summary.
GaussNewtonSummary check_fig4(int refine, bool end_face_markers, const GaussNewtonOptions& options,
                              double shape_tolerance) {
  const int nx = 12 * refine, ny = 3 * refine, nz = 3 * refine;
  const double h = 0.025 / refine;
  const BoxGrid grid{nx, ny, nz};
  const testing::TetMesh mesh = testing::make_box_mesh(nx, ny, nz, h);
  const auto energy = PlasticElasticEnergy::create(mesh.rest_positions, mesh.tets, soft_tissue());
  EXPECT_TRUE(energy.has_value());
  if (!energy) return {};
  const double length = nx * h, width = ny * h;
  BendStretch target;
  target.length = length;
  target.angle = EIGEN_PI / 3;  // 60°: ends turned by ±30°, middle 3.8 cm below the ends
  target.y_centre = width / 2;
  target.z_centre = width / 2;
  target.y_stretch = 2.0;
  BendStretch bend_only = target;
  bend_only.y_stretch = 1.0;

  // Attachments: the y-centre line (y = W/2, four points along z) of each end face, pulled to
  // where the bend puts it. They fix the bend and all rigid motions but say nothing about the
  // y-stretch, which must come from the ICP markers.
  auto locator = TetPointLocator::create(mesh.rest_positions, mesh.tets);
  EXPECT_TRUE(locator.has_value());
  if (!locator) return {};
  RegistrationConstraints constraints;
  for (double x : {0.0, length}) {
    for (int k = 0; k <= nz; ++k) {
      const Eigen::Vector3d X(x, width / 2, k * h);
      const Embedding e = locator->locate(X);
      EXPECT_TRUE(e.ok());
      PointConstraint c;
      c.kind = ConstraintKind::kAttachment;
      c.point = e.point;
      c.target = bend_only(X);
      c.weight = 1e4;  // N/m, stiff against μh ≈ 90 N/m
      constraints.attachments.push_back(c);
    }
  }

  // ICP markers: 15% of the target's surface vertices, as unlabelled world points. The end faces
  // count too (end_face_markers): a scan sees them, and only their centre lines are attached.
  // Without them the ends' outer edges are seen by nothing (648 tets: worst 17 mm there against
  // 3.2 mm on the sides).
  std::vector<int> candidates;
  for (int v = 0; v < mesh.rest_positions.rows(); ++v) {
    const Eigen::Vector3d X = rest_vertex(mesh, v);
    const bool on_side =
        X.y() < 1e-9 || X.y() > width - 1e-9 || X.z() < 1e-9 || X.z() > width - 1e-9;
    const bool on_end = X.x() < 1e-9 || X.x() > length - 1e-9;
    if (end_face_markers ? on_side || on_end : on_side && !on_end) candidates.push_back(v);
  }
  std::mt19937 rng(4);
  std::shuffle(candidates.begin(), candidates.end(), rng);
  const std::size_t marker_count = (candidates.size() * 15) / 100;
  for (std::size_t i = 0; i < marker_count; ++i) {
    constraints.icp_markers.push_back(target(rest_vertex(mesh, candidates[i])));
  }
  auto surface = SurfaceClosestPoint::create(mesh.rest_positions.rows(), mesh.tets);
  EXPECT_TRUE(surface.has_value());
  if (!surface) return {};
  BoundaryClosestPoint closest(*surface);

  // The attachment stage (which follows the constant initial fit, §3.4) sees nothing of the
  // uniform y-stretch (the attachments lie on the plane y = W/2); before
  // GaussNewtonOptions::attachment_stage_damping_floor its Gauss–Newton step along that constant
  // mode collapsed Fp_yy to the 0.01 floor (markers 92 mm off, the middle section 0.22x wide),
  // undoing the initial fit (alone 2.02x wide, 1.00x high).
  const RegistrationResult result = register_attached(*energy, constraints, &closest, options);
  EXPECT_TRUE(result.summary.usable()) << result.summary.full_report();
  std::cout << marker_count << " ICP markers of " << candidates.size() << " surface vertices, "
            << mesh.tets.rows() << " tets\n"
            << result.summary.full_report();
  const Eigen::VectorXd& x = result.x;
  const auto pos = [&](int v) -> Eigen::Vector3d { return x.segment<3>(3 * v); };

  // Markers met.
  std::cout << "Fig. 4: ICP marker error max " << result.summary.marker_error_max * 1e3
            << " mm, mean " << result.summary.marker_error_mean * 1e3 << " mm\n";
  EXPECT_LT(result.summary.marker_error_max, 0.01 * width);

  // Middle cross-section (i = nx/2): width in y and height in z, frame-free (distances between
  // opposite side vertices), relative to the rest's.
  double y_extent = 0.0, z_extent = 0.0;
  for (int k = 0; k <= nz; ++k)
    y_extent += (pos(grid(nx / 2, ny, k)) - pos(grid(nx / 2, 0, k))).norm();
  for (int j = 0; j <= ny; ++j)
    z_extent += (pos(grid(nx / 2, j, nz)) - pos(grid(nx / 2, j, 0))).norm();
  y_extent /= (nz + 1) * width;
  z_extent /= (ny + 1) * width;
  std::cout << "Fig. 4: middle cross-section y extent " << y_extent << "x, z extent " << z_extent
            << "x of the rest\n";
  EXPECT_NEAR(y_extent, 2.0, 0.2);
  EXPECT_NEAR(z_extent, 1.0, 0.1);

  // The bend: end-face centres where the target puts them, and the middle section's centre
  // below the ends by the arc's sagitta.
  const auto section_centre = [&](int i, bool recovered) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (int k = 0; k <= nz; ++k) {
      for (int j = 0; j <= ny; ++j) {
        const int v = grid(i, j, k);
        c += (recovered ? pos(v) : target(rest_vertex(mesh, v))) / ((ny + 1) * (nz + 1));
      }
    }
    return c;
  };
  double end_error = 0.0;
  for (int i : {0, nx}) {
    end_error = std::max(end_error, (section_centre(i, true) - section_centre(i, false)).norm());
  }
  const double sagitta_true = (section_centre(0, false) + section_centre(nx, false)).z() / 2 -
                              section_centre(nx / 2, false).z();
  const double sagitta = (section_centre(0, true) + section_centre(nx, true)).z() / 2 -
                         section_centre(nx / 2, true).z();
  double attachment_error = 0.0;
  for (const PointConstraint& c : constraints.attachments) {
    attachment_error =
        std::max(attachment_error, (embedded_position(mesh.tets, c.point, x) - c.target).norm());
  }
  std::cout << "Fig. 4: attachments met to " << attachment_error * 1e3 << " mm; end-section "
            << "centres off by " << end_error * 1e3 << " mm; sagitta " << sagitta * 1e3
            << " mm (target " << sagitta_true * 1e3 << " mm)\n";
  EXPECT_LT(attachment_error, 1e-3);
  EXPECT_LT(end_error, 0.05 * width);
  // Not asserted: this sagitta follows material sections, which slide along the axis (648 tets:
  // 33.6 mm against 38.4 mm); the two-sided shape error below measures the bend itself.

  // The shape against the target shape, both ways (the ICP markers carry no correspondence, so
  // material may slide along the surface; vertex-to-vertex errors would count that sliding).
  Eigen::VectorXd x_target(x.size());
  for (int v = 0; v < mesh.rest_positions.rows(); ++v) {
    x_target.segment<3>(3 * v) = target(rest_vertex(mesh, v));
  }
  const auto one_sided = [&](const Eigen::VectorXd& from, const Eigen::VectorXd& to) {
    EXPECT_EQ(surface->update(to), SurfaceUpdateStatus::kOk);
    double largest = 0.0;
    for (int v : surface->boundary().vertices()) {
      largest = std::max(largest, surface->query(Eigen::Vector3d(from.segment<3>(3 * v))).distance);
    }
    return largest;
  };
  const double shape_error = std::max(one_sided(x, x_target), one_sided(x_target, x));
  double vertex_error = 0.0;
  for (int v : surface->boundary().vertices()) {
    vertex_error = std::max(vertex_error, (x - x_target).segment<3>(3 * v).norm());
  }
  const double diagonal = std::sqrt(length * length + 2 * width * width);
  std::cout << "Fig. 4: surface to target surface (two-sided, max) " << shape_error * 1e3
            << " mm = " << 100 * shape_error / diagonal << "% of the diagonal; vertex to its "
            << "analytic image " << vertex_error * 1e3 << " mm\n";
  // Material still slides along the axis by several cm (vertex error): the ICP markers carry no
  // correspondence and the Laplacian hardly penalises a linear axial stretch gradient. The shape
  // is what the markers define, and what is checked.
  EXPECT_LT(shape_error, shape_tolerance * diagonal);
  // Principal stretches of Fp in the middle third: the one whose direction is closest to y, and
  // the other two.
  double stretch_y = 0.0, stretch_other_min = 1e9, stretch_other_max = 0.0, stretch_other = 0.0;
  int middle_tets = 0;
  for (Eigen::Index t = 0; t < mesh.tets.rows(); ++t) {
    const double cx = tet_centroid(mesh, t).x();
    if (cx < length / 3 || cx > 2 * length / 3) continue;
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(
        plastic_strain_matrix(result.s.segment<6>(6 * t)));
    int iy = 0;
    eig.eigenvectors().row(1).cwiseAbs().maxCoeff(&iy);
    stretch_y += eig.eigenvalues()[iy];
    for (int a = 0; a < 3; ++a) {
      if (a == iy) continue;
      stretch_other += eig.eigenvalues()[a] / 2;
    }
    ++middle_tets;
  }
  stretch_y /= middle_tets;
  stretch_other /= middle_tets;
  for (Eigen::Index t = 0; t < mesh.tets.rows(); ++t) {
    const double cx = tet_centroid(mesh, t).x();
    if (cx < length / 3 || cx > 2 * length / 3) continue;
    const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(
                                   plastic_strain_matrix(result.s.segment<6>(6 * t)))
                                   .eigenvalues();
    stretch_other_min = std::min(stretch_other_min, ev.minCoeff());
    stretch_other_max = std::max(stretch_other_max, ev.maxCoeff());
  }
  std::cout << "Fig. 4: Fp over " << middle_tets << " middle tets: mean principal stretch along y "
            << stretch_y << ", across " << stretch_other << " (eigenvalues in ["
            << stretch_other_min << ", " << stretch_other_max << "])\n";
  EXPECT_NEAR(stretch_y, 2.0, 0.3);
  EXPECT_NEAR(stretch_other, 1.0, 0.15);
  return result.summary;
}

// Fig. 4 as sinew-register runs it (10 point-to-plane ICP iterations first, its default). Measured:
// markers met to 0.7 µm, middle section 2.006x in y and 1.003x across, Fp stretch 2.00 along y,
// the surface within 0.95% of the diagonal of the target (0.88% before the tie-independent ICP
// normals). With the paper's point-to-point
// ICP throughout (the library default): 2.4%. Before the end faces carried markers: 5.3% (sides
// alone 1.0%).
TEST(PaperFigures, Fig4BentAndTransverselyStretchedBeamIsRecovered) {
  GaussNewtonOptions options;
  options.icp_point_to_plane_iterations = 10;
  check_fig4(1, true, options, 0.015);
}

// The same beam at 5,184 tets with markers on the sides only (82). Measured on every OpenBLAS core
// type (Cooperlake, SkylakeX, Haswell, Sandybridge) and on 1 and 2 threads, identically: markers
// met to 0.13 µm, middle section 2.04x in y and 1.01x across, the surface within 6.30% of the
// diagonal (the worst at the unmarked end faces). This test used to assert 3% (measured 1.95%) and
// that the projected-path search was needed; both held only on machines whose rounding made the
// AABB tree return one particular face for closest points on edges, whose normal then steered the
// point-to-plane ICP stage (AVX-512 kernels: 14.8%, line-search-failed). With the normal a function
// of the closest point alone (BoundaryClosestPoint::normal) the run no longer depends on the
// machine, and it ends at 6.30%. (With the end faces marked too, 97 markers: 1.37% before.)
TEST(PaperFigures, Fig4OnAFinerMeshWithSideMarkersOnly) {
  GaussNewtonOptions options;
  options.icp_point_to_plane_iterations = 10;
  check_fig4(2, false, options, 0.07);
}

// ---------------------------------------------------------------------------------------------
// Fig. 2: the spike of the FEM static baseline under a point constraint.

// |u(pulled)| / mean |u(v)| over the other vertices within `radius` of the pulled one (rest
// distances).
double spike_ratio(const testing::TetMesh& mesh, const Eigen::VectorXd& rest,
                   const Eigen::VectorXd& x, int pulled, double radius, int* neighbours) {
  const Eigen::Vector3d P = rest_vertex(mesh, pulled);
  double sum = 0.0;
  int count = 0;
  for (int v = 0; v < mesh.rest_positions.rows(); ++v) {
    if (v == pulled || (rest_vertex(mesh, v) - P).norm() > radius + 1e-9) continue;
    sum += (x - rest).segment<3>(3 * v).norm();
    ++count;
  }
  if (neighbours != nullptr) *neighbours = count;
  return (x - rest).segment<3>(3 * pulled).norm() / (sum / count);
}

TEST(PaperFigures, Fig2FemStaticSpikesWherePlasticRegistrationSpreads) {
  // A block of 6x6x4 cubes of 2.5 cm (0.15 x 0.15 x 0.1 m, 864 tets), fixed at its bottom like
  // the bunny; the centre vertex of the top face is pulled up by `pull`.
  constexpr int nx = 6, ny = 6, nz = 4;
  constexpr double h = 0.025;
  const BoxGrid grid{nx, ny, nz};
  const testing::TetMesh mesh = testing::make_box_mesh(nx, ny, nz, h);
  const auto energy = PlasticElasticEnergy::create(mesh.rest_positions, mesh.tets, soft_tissue());
  ASSERT_TRUE(energy.has_value());
  const Eigen::VectorXd& rest = energy->rest_dofs();
  const int pulled = grid(nx / 2, ny / 2, nz);
  const double pull = 0.03;  // m: 30% of the block's height, 1.2 element lengths
  const Eigen::Vector3d pulled_target = rest_vertex(mesh, pulled) + Eigen::Vector3d(0, 0, pull);

  std::vector<PointConstraint> attachments;
  for (int v = 0; v < mesh.rest_positions.rows(); ++v) {
    if (mesh.rest_positions(v, 2) > 1e-9) continue;
    PointConstraint c;
    c.kind = ConstraintKind::kAttachment;
    c.point = at_vertex(mesh.tets, v);
    c.target = rest_vertex(mesh, v);
    c.weight = 1e4;
    attachments.push_back(c);
  }

  // FEM static: s = identity, the point constraint a stiff spring among the attachments.
  std::vector<PointConstraint> springs_with_point = attachments;
  {
    PointConstraint c;
    c.kind = ConstraintKind::kAttachment;
    c.point = at_vertex(mesh.tets, pulled);
    c.target = pulled_target;
    c.weight = 1e4;
    springs_with_point.push_back(c);
  }
  auto springs =
      PointConstraints::create(mesh.rest_positions.rows(), mesh.tets, springs_with_point);
  ASSERT_TRUE(springs.has_value());
  auto equilibrium = EquilibriumSolver::create(*energy, *springs);
  ASSERT_TRUE(equilibrium.has_value());
  Eigen::VectorXd x_fem = rest;
  const EquilibriumSummary fem =
      equilibrium->solve(identity_plastic_strains(mesh.tets.rows()), x_fem);
  ASSERT_TRUE(fem.converged()) << fem.full_report();

  // Plastic-strain registration: the same point as a landmark with correspondence.
  RegistrationConstraints constraints;
  constraints.attachments = attachments;
  PointConstraint landmark;
  landmark.kind = ConstraintKind::kLandmark;
  landmark.point = at_vertex(mesh.tets, pulled);
  landmark.target = pulled_target;
  constraints.landmarks.push_back(landmark);
  const RegistrationResult plastic = register_attached(*energy, constraints, nullptr);
  ASSERT_TRUE(plastic.summary.usable()) << plastic.summary.full_report();

  int neighbours = 0;
  const double radius = 2 * h;
  const double fem_ratio = spike_ratio(mesh, rest, x_fem, pulled, radius, &neighbours);
  const double plastic_ratio = spike_ratio(mesh, rest, plastic.x, pulled, radius, nullptr);
  const double fem_reached = (x_fem - rest).segment<3>(3 * pulled).norm();
  const double plastic_reached = (plastic.x - rest).segment<3>(3 * pulled).norm();
  std::cout << "Fig. 2: pulled vertex moved " << fem_reached * 1e3 << " mm (FEM static) / "
            << plastic_reached * 1e3 << " mm (plastic) of " << pull * 1e3 << " mm; spike ratio "
            << "(its displacement / mean over the " << neighbours << " vertices within 2h): FEM "
            << fem_ratio << ", plastic " << plastic_ratio << "\n"
            << plastic.summary.brief_report() << "\n";
  EXPECT_GT(fem_reached, 0.5 * pull);
  EXPECT_NEAR(plastic_reached, pull, 0.05 * pull);
  EXPECT_GE(fem_ratio, 3.0);
  EXPECT_LE(plastic_ratio, 2.0);
  EXPECT_GE(fem_ratio, 2.0 * plastic_ratio);
}

}  // namespace
}  // namespace sinew::offline
