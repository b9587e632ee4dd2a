#include "offline/meshing/tet_mesher.hpp"
#include "common/timing.hpp"

// CGAL is confined to this translation unit (and surface_closest_point.cpp).
#include <CGAL/AABB_face_graph_triangle_primitive.h>
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/ImageIO.h>
#include <CGAL/Image_3.h>
#include <CGAL/Labeled_mesh_domain_3.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_optimization_return_code.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Polygon_mesh_processing/compute_normal.h>
#include <CGAL/Polygon_mesh_processing/orientation.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Polyhedral_mesh_domain_with_features_3.h>
#include <CGAL/Random.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/exude_mesh_3.h>
#include <CGAL/lloyd_optimize_mesh_3.h>
#include <CGAL/make_mesh_3.h>
#include <CGAL/odt_optimize_mesh_3.h>
#include <CGAL/perturb_mesh_3.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <exception>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <type_traits>
#include <utility>
#include <vector>

namespace sinew::offline {
namespace {

using Clock = std::chrono::steady_clock;

using common::seconds_since;

constexpr double kPi = 3.14159265358979323846;

// ----------------------------------------------------------------------------------------------
// Input checks (plain Eigen / std): every problem is one line naming the offending entity.
// ----------------------------------------------------------------------------------------------

struct SurfaceCheck {
  TetMesherStatus status = TetMesherStatus::kOk;
  std::string message;
};

SurfaceCheck fail(TetMesherStatus status, const std::string& message) {
  return SurfaceCheck{status, message};
}

/// Shapes, indices, finiteness, degenerate faces. Fills the bounding-box diagonal.
SurfaceCheck check_shapes(const Eigen::Ref<const Eigen::MatrixXd>& V,
                          const Eigen::Ref<const Eigen::MatrixXi>& F, double* diagonal) {
  std::ostringstream s;
  if (V.cols() != 3) {
    s << "vertices must be #V by 3, got " << V.rows() << " by " << V.cols();
    return fail(TetMesherStatus::kInvalidSurface, s.str());
  }
  if (F.cols() != 3) {
    s << "faces must be #F by 3 (triangles), got " << F.rows() << " by " << F.cols();
    return fail(TetMesherStatus::kInvalidSurface, s.str());
  }
  if (F.rows() < 4) {
    s << "a closed surface needs at least 4 faces, got " << F.rows();
    return fail(TetMesherStatus::kInvalidSurface, s.str());
  }
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    for (int a = 0; a < 3; ++a) {
      const int v = F(f, a);
      if (v < 0 || v >= V.rows()) {
        s << "face " << f << " references vertex " << v << ", but there are " << V.rows()
          << " vertices";
        return fail(TetMesherStatus::kInvalidSurface, s.str());
      }
      if (!V.row(v).allFinite()) {
        s << "vertex " << v << " (of face " << f << ") has non-finite coordinates";
        return fail(TetMesherStatus::kInvalidSurface, s.str());
      }
      lo = lo.cwiseMin(V.row(v).transpose());
      hi = hi.cwiseMax(V.row(v).transpose());
    }
    if (F(f, 0) == F(f, 1) || F(f, 1) == F(f, 2) || F(f, 0) == F(f, 2)) {
      s << "face " << f << " repeats a vertex (" << F(f, 0) << ", " << F(f, 1) << ", " << F(f, 2)
        << ")";
      return fail(TetMesherStatus::kInvalidSurface, s.str());
    }
  }
  *diagonal = (hi - lo).norm();
  if (!(*diagonal > 0.0)) return fail(TetMesherStatus::kInvalidSurface, "all vertices coincide");
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const Eigen::Vector3d a = V.row(F(f, 0)), b = V.row(F(f, 1)), c = V.row(F(f, 2));
    const double area = 0.5 * (b - a).cross(c - a).norm();
    if (!(area > 1e-12 * *diagonal * *diagonal)) {
      s << "face " << f << " is degenerate (area " << area << ", bounding-box diagonal "
        << *diagonal << ")";
      return fail(TetMesherStatus::kInvalidSurface, s.str());
    }
  }
  return {};
}

/// Every edge in exactly two faces, traversed in opposite directions; every vertex's faces form
/// one fan (no pinched vertices).
SurfaceCheck check_topology(const Eigen::Ref<const Eigen::MatrixXi>& F) {
  struct HalfEdge {
    int lo, hi;  // undirected key
    int from;    // direction
    Eigen::Index face;
  };
  std::vector<HalfEdge> edges;
  edges.reserve(static_cast<std::size_t>(3 * F.rows()));
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    for (int a = 0; a < 3; ++a) {
      const int u = F(f, a), v = F(f, (a + 1) % 3);
      edges.push_back({std::min(u, v), std::max(u, v), u, f});
    }
  }
  std::sort(edges.begin(), edges.end(), [](const HalfEdge& x, const HalfEdge& y) {
    return std::tie(x.lo, x.hi, x.face) < std::tie(y.lo, y.hi, y.face);
  });
  std::size_t open = 0;
  std::optional<HalfEdge> first_open;
  for (std::size_t i = 0; i < edges.size();) {
    std::size_t j = i;
    while (j < edges.size() && edges[j].lo == edges[i].lo && edges[j].hi == edges[i].hi) ++j;
    const std::size_t count = j - i;
    std::ostringstream s;
    if (count > 2) {
      s << "the surface is not manifold: edge (" << edges[i].lo << ", " << edges[i].hi
        << ") is shared by " << count << " faces (" << edges[i].face << ", " << edges[i + 1].face
        << ", " << edges[i + 2].face << (count > 3 ? ", ..." : "") << ")";
      return fail(TetMesherStatus::kNonManifoldSurface, s.str());
    }
    if (count == 2 && edges[i].from == edges[i + 1].from) {
      s << "the surface is not consistently oriented: faces " << edges[i].face << " and "
        << edges[i + 1].face << " traverse edge (" << edges[i].lo << ", " << edges[i].hi
        << ") in the same direction";
      return fail(TetMesherStatus::kNonManifoldSurface, s.str());
    }
    if (count == 1) {
      if (!first_open) first_open = edges[i];
      ++open;
    }
    i = j;
  }
  if (open > 0) {
    std::ostringstream s;
    s << "the surface is open: " << open << " edge" << (open > 1 ? "s belong" : " belongs")
      << " to one face only, e.g. edge (" << first_open->lo << ", " << first_open->hi
      << ") of face " << first_open->face;
    return fail(TetMesherStatus::kOpenSurface, s.str());
  }

  // Link of vertex a: for each face (a, b, c) the directed edge b -> c. On a closed, consistently
  // oriented, edge-manifold surface each b occurs once as a source; the vertex is manifold iff
  // following the links from any start visits all of them.
  struct Link {
    int vertex, from, to;
  };
  std::vector<Link> links;
  links.reserve(static_cast<std::size_t>(3 * F.rows()));
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    for (int a = 0; a < 3; ++a) links.push_back({F(f, a), F(f, (a + 1) % 3), F(f, (a + 2) % 3)});
  }
  std::sort(links.begin(), links.end(), [](const Link& x, const Link& y) {
    return std::tie(x.vertex, x.from) < std::tie(y.vertex, y.from);
  });
  for (std::size_t i = 0; i < links.size();) {
    std::size_t j = i;
    while (j < links.size() && links[j].vertex == links[i].vertex) ++j;
    const auto begin = links.begin() + static_cast<std::ptrdiff_t>(i);
    const auto end = links.begin() + static_cast<std::ptrdiff_t>(j);
    std::size_t steps = 0;
    int current = links[i].from;
    do {
      const auto it = std::lower_bound(begin, end, current,
                                       [](const Link& l, int from) { return l.from < from; });
      if (it == end || it->from != current) break;  // cannot happen after the edge checks
      current = it->to;
      ++steps;
    } while (current != links[i].from && steps <= j - i);
    if (steps != j - i) {
      std::ostringstream s;
      s << "the surface is not manifold at vertex " << links[i].vertex << ": its " << (j - i)
        << " faces form more than one fan (pinched vertex)";
      return fail(TetMesherStatus::kNonManifoldSurface, s.str());
    }
    i = j;
  }
  return {};
}

/// Σ a·(b×c)/6 over the faces, relative to the first vertex (less cancellation).
double enclosed_volume(const Eigen::Ref<const Eigen::MatrixXd>& V,
                       const Eigen::Ref<const Eigen::MatrixXi>& F) {
  const Eigen::Vector3d o = V.row(F(0, 0));
  double six_volume = 0.0;
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const Eigen::Vector3d a = V.row(F(f, 0)).transpose() - o;
    const Eigen::Vector3d b = V.row(F(f, 1)).transpose() - o;
    const Eigen::Vector3d c = V.row(F(f, 2)).transpose() - o;
    six_volume += a.dot(b.cross(c));
  }
  return six_volume / 6.0;
}

// ----------------------------------------------------------------------------------------------
// Tet quality
// ----------------------------------------------------------------------------------------------

/// The six dihedral angles (radians) of the tet with vertices p.
std::array<double, 6> dihedral_angles(const std::array<Eigen::Vector3d, 4>& p) {
  static constexpr int kEdges[6][4] = {{0, 1, 2, 3}, {0, 2, 1, 3}, {0, 3, 1, 2},
                                       {1, 2, 0, 3}, {1, 3, 0, 2}, {2, 3, 0, 1}};
  std::array<double, 6> angles{};
  for (int e = 0; e < 6; ++e) {
    const Eigen::Vector3d& a = p[kEdges[e][0]];
    const Eigen::Vector3d d = (p[kEdges[e][1]] - a).normalized();
    Eigen::Vector3d u = p[kEdges[e][2]] - a;
    Eigen::Vector3d w = p[kEdges[e][3]] - a;
    u -= u.dot(d) * d;  // components perpendicular to the edge span the two faces' half-planes
    w -= w.dot(d) * d;
    angles[static_cast<std::size_t>(e)] = std::atan2(u.cross(w).norm(), u.dot(w));
  }
  return angles;
}

/// 3·r_in / R_circ (1 for the regular tet).
double radius_ratio(const std::array<Eigen::Vector3d, 4>& p) {
  const Eigen::Vector3d a = p[1] - p[0], b = p[2] - p[0], c = p[3] - p[0];
  const double six_volume = std::abs(a.dot(b.cross(c)));
  const double area = 0.5 * (a.cross(b).norm() + b.cross(c).norm() + c.cross(a).norm() +
                             (p[2] - p[1]).cross(p[3] - p[1]).norm());
  if (!(six_volume > 0.0) || !(area > 0.0)) return 0.0;
  const double r_in = 0.5 * six_volume / area;  // 3V / A
  const double r_circ =
      (a.squaredNorm() * b.cross(c) + b.squaredNorm() * c.cross(a) + c.squaredNorm() * a.cross(b))
          .norm() /
      (2.0 * six_volume);
  return 3.0 * r_in / r_circ;
}

void fill_quality(const TetMesh& mesh, TetMesherSummary* summary) {
  const TetMeshQuality q = tet_mesh_quality(mesh);
  summary->tet_volume = q.volume;
  if (mesh.tets.rows() == 0) return;
  summary->min_dihedral_degrees = q.min_dihedral_degrees;
  summary->max_dihedral_degrees = q.max_dihedral_degrees;
  summary->min_radius_ratio = q.min_radius_ratio;
  summary->mean_radius_ratio = q.mean_radius_ratio;
}

Eigen::Index count_boundary_faces(const TetMesh& mesh) {
  std::vector<std::array<int, 3>> faces;
  faces.reserve(static_cast<std::size_t>(4 * mesh.tets.rows()));
  for (Eigen::Index t = 0; t < mesh.tets.rows(); ++t) {
    for (int skip = 0; skip < 4; ++skip) {
      std::array<int, 3> f{};
      int k = 0;
      for (int a = 0; a < 4; ++a) {
        if (a != skip) f[static_cast<std::size_t>(k++)] = mesh.tets(t, a);
      }
      std::sort(f.begin(), f.end());
      faces.push_back(f);
    }
  }
  std::sort(faces.begin(), faces.end());
  Eigen::Index boundary = 0;
  for (std::size_t i = 0; i < faces.size();) {
    std::size_t j = i;
    while (j < faces.size() && faces[j] == faces[i]) ++j;
    if (j - i == 1) ++boundary;
    i = j;
  }
  return boundary;
}

// ----------------------------------------------------------------------------------------------
// CGAL
// ----------------------------------------------------------------------------------------------

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using SurfaceMesh = CGAL::Surface_mesh<Kernel::Point_3>;
using MeshDomain = CGAL::Polyhedral_mesh_domain_with_features_3<Kernel, SurfaceMesh>;
using Triangulation =
    CGAL::Mesh_triangulation_3<MeshDomain, CGAL::Default, CGAL::Sequential_tag>::type;
using Complex = CGAL::Mesh_complex_3_in_triangulation_3<Triangulation, MeshDomain::Corner_index,
                                                        MeshDomain::Curve_index>;
using Criteria = CGAL::Mesh_criteria_3<Triangulation>;
// Scalar images (a smoothed label mask): the region where the trilinear interpolation > iso.
using ImageDomain = CGAL::Labeled_mesh_domain_3<Kernel>;
using ImageTriangulation =
    CGAL::Mesh_triangulation_3<ImageDomain, CGAL::Default, CGAL::Sequential_tag>::type;
using ImageComplex = CGAL::Mesh_complex_3_in_triangulation_3<ImageTriangulation>;

/// The size field of TetMesherOptions::tets_across_thickness: min(largest, thickness / across),
/// at least smallest, with the thickness at p the chord through the solid along the inward normal
/// of the surface face closest to p (the first hit of a ray cast inwards from just inside it);
/// with thin_fraction > 0 only where the thickness is below thin_fraction times the surface's
/// median thickness (TetMesherOptions::thin_fraction_of_median), largest elsewhere.
class ThicknessSizing {
 public:
  using FT = Kernel::FT;
  ThicknessSizing(const SurfaceMesh& surface, double largest, double smallest, double across,
                  double thin_fraction)
      : surface_(&surface),
        tree_(std::make_shared<Tree>(faces(surface).first, faces(surface).second, surface)),
        largest_(largest),
        smallest_(smallest),
        across_(across),
        inward_(CGAL::Polygon_mesh_processing::is_outward_oriented(surface) ? -1.0 : 1.0) {
    tree_->accelerate_distance_queries();
    if (thin_fraction > 0.0) thin_below_ = thin_fraction * median_thickness();
  }

  /// The thickness at the faces' centroids, the median weighted by the faces' areas.
  double median_thickness() const {
    std::vector<std::pair<double, double>> samples;  // (thickness, area)
    double total = 0.0;
    for (const auto f : faces(*surface_)) {
      const auto h = halfedge(f, *surface_);
      const Kernel::Point_3& a = surface_->point(source(h, *surface_));
      const Kernel::Point_3& b = surface_->point(target(h, *surface_));
      const Kernel::Point_3& c = surface_->point(target(next(h, *surface_), *surface_));
      const double area = std::sqrt(CGAL::squared_area(a, b, c));
      samples.emplace_back(thickness(CGAL::centroid(a, b, c)), area);
      total += area;
    }
    std::sort(samples.begin(), samples.end());
    double sum = 0.0;
    for (const auto& [t, area] : samples) {
      sum += area;
      if (sum >= 0.5 * total) return t;
    }
    return samples.empty() ? largest_ * across_ : samples.back().first;
  }

  /// The chord length through the solid at p (largest·across when the ray finds no exit).
  double thickness(const Kernel::Point_3& p) const {
    const auto [q, face] = tree_->closest_point_and_primitive(p);
    const Kernel::Vector_3 n =
        inward_ * CGAL::Polygon_mesh_processing::compute_face_normal(face, *surface_);
    const double offset = 1e-6 * largest_;
    const Kernel::Point_3 start = q + offset * n;
    const auto hit = tree_->first_intersection(Kernel::Ray_3(start, n));
    if (!hit) return largest_ * across_;
    if (const auto* point = boost::get<Kernel::Point_3>(&hit->first)) {
      return std::sqrt(CGAL::squared_distance(start, *point)) + offset;
    }
    return largest_ * across_;  // a ray along a face (a segment hit): no usable chord
  }

  template <class Index>
  FT operator()(const Kernel::Point_3& p, const int /*dimension*/, const Index& /*index*/) const {
    const double t = thickness(p);
    if (t >= thin_below_) return largest_;
    return std::clamp(t / across_, smallest_, largest_);
  }

 private:
  using Primitive = CGAL::AABB_face_graph_triangle_primitive<SurfaceMesh>;
  using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, Primitive>>;
  const SurfaceMesh* surface_;
  std::shared_ptr<Tree> tree_;  // shared: Mesh_3 copies its criteria
  double largest_, smallest_, across_;
  double inward_;  // −1 when the faces are oriented outwards (their normals then point out)
  double thin_below_ = std::numeric_limits<double>::infinity();
};

/// Surface_mesh of the referenced vertices (renumbered) and the faces. False if CGAL refuses a
/// face (non-manifold configuration missed by the checks).
bool build_surface_mesh(const Eigen::Ref<const Eigen::MatrixXd>& V,
                        const Eigen::Ref<const Eigen::MatrixXi>& F, SurfaceMesh* sm) {
  std::vector<SurfaceMesh::Vertex_index> handle(static_cast<std::size_t>(V.rows()),
                                                SurfaceMesh::null_vertex());
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    std::array<SurfaceMesh::Vertex_index, 3> v;
    for (int a = 0; a < 3; ++a) {
      auto& h = handle[static_cast<std::size_t>(F(f, a))];
      if (h == SurfaceMesh::null_vertex()) {
        h = sm->add_vertex(Kernel::Point_3(V(F(f, a), 0), V(F(f, a), 1), V(F(f, a), 2)));
      }
      v[static_cast<std::size_t>(a)] = h;
    }
    if (sm->add_face(v[0], v[1], v[2]) == SurfaceMesh::null_face()) return false;
  }
  return true;
}

/// Cells of the complex as a right-handed tet mesh over the vertices they use (first-use order).
template <class C3T3>
TetMesh extract_tets(const C3T3& c3t3, int* flipped) {
  std::map<typename C3T3::Triangulation::Vertex_handle, int> index;
  std::vector<Eigen::Vector3d> points;
  std::vector<std::array<int, 4>> tets;
  tets.reserve(c3t3.number_of_cells_in_complex());
  for (auto c = c3t3.cells_in_complex_begin(); c != c3t3.cells_in_complex_end(); ++c) {
    std::array<int, 4> tet{};
    for (int a = 0; a < 4; ++a) {
      const auto v = c->vertex(a);
      const auto [it, inserted] = index.emplace(v, static_cast<int>(points.size()));
      if (inserted) {
        const auto& p = v->point().point();
        points.emplace_back(p.x(), p.y(), p.z());
      }
      tet[static_cast<std::size_t>(a)] = it->second;
    }
    tets.push_back(tet);
  }
  TetMesh mesh;
  mesh.vertices.resize(static_cast<Eigen::Index>(points.size()), 3);
  for (std::size_t i = 0; i < points.size(); ++i)
    mesh.vertices.row(static_cast<Eigen::Index>(i)) = points[i].transpose();
  mesh.tets.resize(static_cast<Eigen::Index>(tets.size()), 4);
  *flipped = 0;
  for (std::size_t t = 0; t < tets.size(); ++t) {
    auto& tet = tets[t];
    const Eigen::Vector3d& p0 = points[static_cast<std::size_t>(tet[0])];
    const double six_volume = (points[static_cast<std::size_t>(tet[1])] - p0)
                                  .dot((points[static_cast<std::size_t>(tet[2])] - p0)
                                           .cross(points[static_cast<std::size_t>(tet[3])] - p0));
    if (six_volume < 0.0) {
      std::swap(tet[2], tet[3]);
      ++*flipped;
    }
    for (int a = 0; a < 4; ++a)
      mesh.tets(static_cast<Eigen::Index>(t), a) = tet[static_cast<std::size_t>(a)];
  }
  return mesh;
}

/// CGAL Mesh_3 on a domain: refinement with the size criteria of options (relative to diagonal),
/// then ODT / Lloyd / perturbation / exudation as asked, and the cells as a right-handed tet mesh
/// into result. A failure status and message, or std::nullopt.
template <class C3T3, class Domain>
std::optional<std::pair<TetMesherStatus, std::string>> refine_and_optimise(
    const Domain& domain, bool features, double diagonal, const TetMesherOptions& options,
    TetMesherResult& result, Clock::time_point meshing_start,
    const SurfaceMesh* surface = nullptr) {
  TetMesherSummary& summary = result.summary;
  namespace p = CGAL::parameters;
  const double cell_size = options.cell_size_fraction * diagonal;
  using Criteria3 = CGAL::Mesh_criteria_3<typename C3T3::Triangulation>;
  const Criteria3 criteria = [&] {
    if (surface != nullptr && options.tets_across_thickness > 0.0) {
      const ThicknessSizing sizing(*surface, cell_size,
                                   std::min(cell_size, options.min_size_fraction * diagonal),
                                   options.tets_across_thickness, options.thin_fraction_of_median);
      return Criteria3(
          p::edge_size = cell_size, p::facet_angle = options.facet_angle_degrees,
          p::facet_size = sizing, p::facet_distance = options.facet_distance_fraction * diagonal,
          p::cell_radius_edge_ratio = options.cell_radius_edge_ratio, p::cell_size = sizing);
    }
    return Criteria3(
        p::edge_size = cell_size, p::facet_angle = options.facet_angle_degrees,
        p::facet_size = cell_size, p::facet_distance = options.facet_distance_fraction * diagonal,
        p::cell_radius_edge_ratio = options.cell_radius_edge_ratio, p::cell_size = cell_size);
  }();

  // Refinement, then each optimisation phase on its own (timed, return code read). Time limits
  // are explicit: make_mesh_3's default for perturbation and exudation (the refinement time)
  // would make the output depend on the machine's load.
  CGAL::Mesh_error_code error_code = CGAL::CGAL_MESH_3_NO_ERROR;
  auto phase_start = Clock::now();
  C3T3 c3t3;
  if constexpr (std::is_same_v<Domain, MeshDomain>) {
    c3t3 = CGAL::make_mesh_3<C3T3>(
        domain, criteria, features ? p::features(domain) : p::no_features(), p::no_odt(),
        p::no_lloyd(), p::no_perturb(), p::no_exude(),
        p::mesh_3_options(
            p::maximal_number_of_vertices = static_cast<std::size_t>(options.max_vertices),
            p::pointer_to_error_code = &error_code));
  } else {
    c3t3 = CGAL::make_mesh_3<C3T3>(
        domain, criteria, p::no_features(), p::no_odt(), p::no_lloyd(), p::no_perturb(),
        p::no_exude(),
        p::mesh_3_options(
            p::maximal_number_of_vertices = static_cast<std::size_t>(options.max_vertices),
            p::pointer_to_error_code = &error_code));
  }
  summary.refine_seconds = seconds_since(phase_start);
  if (error_code == CGAL::CGAL_MESH_3_MAXIMAL_NUMBER_OF_VERTICES_REACHED) {
    summary.meshing_seconds = seconds_since(meshing_start);
    std::ostringstream s;
    s << "refinement reached max_vertices = " << options.max_vertices << " (cell_size_fraction "
      << options.cell_size_fraction << ", facet_distance_fraction "
      << options.facet_distance_fraction << ")";
    return std::pair{TetMesherStatus::kVertexLimitReached, s.str()};
  }
  if (error_code != CGAL::CGAL_MESH_3_NO_ERROR) {
    summary.meshing_seconds = seconds_since(meshing_start);
    return std::pair{TetMesherStatus::kCgalFailed,
                     std::string(CGAL::mesh_error_string(error_code))};
  }
  const int iterations = options.smoothing_iterations;
  if (options.odt) {
    phase_start = Clock::now();
    CGAL::odt_optimize_mesh_3(c3t3, domain, p::time_limit = 0,
                              p::max_iteration_number = iterations);
    summary.odt_seconds = seconds_since(phase_start);
  }
  if (options.lloyd) {
    phase_start = Clock::now();
    CGAL::lloyd_optimize_mesh_3(c3t3, domain, p::time_limit = 0,
                                p::max_iteration_number = iterations);
    summary.lloyd_seconds = seconds_since(phase_start);
  }
  const double time_limit = options.optimisation_time_limit_seconds;
  if (options.perturb) {
    phase_start = Clock::now();
    const auto code = CGAL::perturb_mesh_3(c3t3, domain, p::time_limit = time_limit,
                                           p::sliver_bound = options.sliver_bound_degrees);
    summary.perturb_seconds = seconds_since(phase_start);
    summary.time_limit_reached |= code == CGAL::TIME_LIMIT_REACHED;
  }
  if (options.exude) {
    phase_start = Clock::now();
    const auto code = CGAL::exude_mesh_3(c3t3, p::time_limit = time_limit,
                                         p::sliver_bound = options.sliver_bound_degrees);
    summary.exude_seconds = seconds_since(phase_start);
    summary.time_limit_reached |= code == CGAL::TIME_LIMIT_REACHED;
  }
  summary.meshing_seconds = seconds_since(meshing_start);
  result.mesh = extract_tets(c3t3, &summary.flipped_tets);
  return std::nullopt;
}

}  // namespace

std::optional<std::string> TetMesherOptions::validate() const {
  std::ostringstream s;
  if (!(cell_size_fraction > 0.0 && cell_size_fraction <= 1.0)) {
    s << "cell_size_fraction = " << cell_size_fraction << " must be in (0, 1]";
  } else if (!(tets_across_thickness >= 0.0 && std::isfinite(tets_across_thickness))) {
    s << "tets_across_thickness = " << tets_across_thickness << " must be >= 0";
  } else if (!(thin_fraction_of_median >= 0.0 && std::isfinite(thin_fraction_of_median))) {
    s << "thin_fraction_of_median = " << thin_fraction_of_median << " must be >= 0";
  } else if (!(min_size_fraction > 0.0 && min_size_fraction <= 1.0)) {
    s << "min_size_fraction = " << min_size_fraction << " must be in (0, 1]";
  } else if (!(facet_distance_fraction > 0.0 && facet_distance_fraction <= 1.0)) {
    s << "facet_distance_fraction = " << facet_distance_fraction << " must be in (0, 1]";
  } else if (!(facet_angle_degrees > 0.0 && facet_angle_degrees <= 30.0)) {
    s << "facet_angle_degrees = " << facet_angle_degrees
      << " must be in (0, 30] (CGAL terminates only up to 30 degrees)";
  } else if (!(cell_radius_edge_ratio >= 2.0 && std::isfinite(cell_radius_edge_ratio))) {
    s << "cell_radius_edge_ratio = " << cell_radius_edge_ratio
      << " must be finite and >= 2 (CGAL terminates only for ratios >= 2)";
  } else if (!(smoothing_iterations >= 1 && smoothing_iterations <= 1000)) {
    s << "smoothing_iterations = " << smoothing_iterations << " must be in [1, 1000]";
  } else if (!(sliver_bound_degrees > 0.0 && sliver_bound_degrees < 60.0)) {
    s << "sliver_bound_degrees = " << sliver_bound_degrees << " must be in (0, 60)";
  } else if (!(optimisation_time_limit_seconds >= 0.0 &&
               std::isfinite(optimisation_time_limit_seconds))) {
    s << "optimisation_time_limit_seconds = " << optimisation_time_limit_seconds
      << " must be finite and >= 0 (0: no limit)";
  } else if (!(feature_angle_degrees > 0.0 && feature_angle_degrees < 180.0)) {
    s << "feature_angle_degrees = " << feature_angle_degrees << " must be in (0, 180)";
  } else if (!(max_vertices >= 4 && max_vertices <= 100'000'000)) {
    s << "max_vertices = " << max_vertices << " must be in [4, 100000000]";
  } else {
    return std::nullopt;
  }
  return s.str();
}

const char* to_string(TetMesherStatus status) {
  switch (status) {
    case TetMesherStatus::kOk:
      return "ok";
    case TetMesherStatus::kInvalidOptions:
      return "invalid options";
    case TetMesherStatus::kInvalidSurface:
      return "invalid surface";
    case TetMesherStatus::kOpenSurface:
      return "open surface";
    case TetMesherStatus::kNonManifoldSurface:
      return "non-manifold surface";
    case TetMesherStatus::kSelfIntersecting:
      return "self-intersecting surface";
    case TetMesherStatus::kVertexLimitReached:
      return "vertex limit reached";
    case TetMesherStatus::kCgalFailed:
      return "CGAL failed";
    case TetMesherStatus::kEmptyMesh:
      return "empty mesh";
  }
  return "unknown";
}

std::string TetMesherSummary::brief_report() const {
  std::ostringstream s;
  s << "Tet mesher: " << to_string(status);
  if (!ok()) {
    s << ": " << message << " (" << seconds << " s)";
    return s.str();
  }
  s << ", " << num_vertices << " vertices, " << num_tets << " tets, dihedral ["
    << *min_dihedral_degrees << ", " << *max_dihedral_degrees << "] deg, min radius ratio "
    << *min_radius_ratio << ", " << seconds << " s";
  return s.str();
}

std::string TetMesherSummary::full_report() const {
  std::ostringstream s;
  const auto optional = [&s](const std::optional<double>& v) {
    if (v) {
      s << *v;
    } else {
      s << "n/a";
    }
    s << "\n";
  };
  s << "Tet mesher\n"
    << "  status:                 " << to_string(status) << "\n";
  if (!message.empty()) s << "  message:                " << message << "\n";
  s << "  input vertices / faces: " << input_vertices << " / " << input_faces << "\n"
    << "  input inward oriented:  " << (input_inward_oriented ? "yes" : "no") << "\n"
    << "  bounding-box diagonal:  " << bounding_box_diagonal << "\n"
    << "  enclosed volume:        " << enclosed_volume << "\n"
    << "  vertices / tets:        " << num_vertices << " / " << num_tets << "\n"
    << "  boundary faces:         " << num_boundary_faces << "\n"
    << "  flipped tets:           " << flipped_tets << "\n"
    << "  tet volume:             " << tet_volume << "\n"
    << "  min dihedral (deg):     ";
  optional(min_dihedral_degrees);
  s << "  max dihedral (deg):     ";
  optional(max_dihedral_degrees);
  s << "  min radius ratio:       ";
  optional(min_radius_ratio);
  s << "  mean radius ratio:      ";
  optional(mean_radius_ratio);
  s << "  time limit reached:     " << (time_limit_reached ? "yes (not reproducible)" : "no")
    << "\n"
    << "  check time (s):         " << check_seconds << "\n"
    << "  meshing time (s):       " << meshing_seconds << "\n"
    << "    refine / odt / lloyd: " << refine_seconds << " / " << odt_seconds << " / "
    << lloyd_seconds << "\n"
    << "    perturb / exude:      " << perturb_seconds << " / " << exude_seconds << "\n"
    << "  total time (s):         " << seconds << "\n";
  return s.str();
}

TetMesherResult make_tet_mesh(const Eigen::Ref<const Eigen::MatrixXd>& vertices,
                              const Eigen::Ref<const Eigen::MatrixXi>& faces,
                              const TetMesherOptions& options) {
  const auto start = Clock::now();
  TetMesherResult result;
  TetMesherSummary& summary = result.summary;
  summary.input_vertices = vertices.rows();
  summary.input_faces = faces.rows();
  const auto finish = [&](TetMesherStatus status, std::string message) {
    summary.status = status;
    summary.message = std::move(message);
    if (status != TetMesherStatus::kOk) result.mesh = TetMesh{};
    summary.seconds = seconds_since(start);
    return result;
  };

  if (const auto error = options.validate())
    return finish(TetMesherStatus::kInvalidOptions, *error);

  // Input checks.
  SurfaceCheck check = check_shapes(vertices, faces, &summary.bounding_box_diagonal);
  if (check.status == TetMesherStatus::kOk) check = check_topology(faces);
  if (check.status != TetMesherStatus::kOk) {
    summary.check_seconds = seconds_since(start);
    return finish(check.status, check.message);
  }
  summary.enclosed_volume = enclosed_volume(vertices, faces);
  summary.input_inward_oriented = summary.enclosed_volume < 0.0;
  summary.enclosed_volume = std::abs(summary.enclosed_volume);

  const double diagonal = summary.bounding_box_diagonal;
  auto meshing_start = Clock::now();
  try {
    SurfaceMesh sm;
    if (!build_surface_mesh(vertices, faces, &sm)) {
      summary.check_seconds = seconds_since(start);
      return finish(TetMesherStatus::kNonManifoldSurface,
                    "CGAL rejected a face of the surface as non-manifold");
    }
    // The first intersecting pair found (not the first by index: the search is box-ordered).
    // Faces of sm are the input faces in order (build_surface_mesh adds each one).
    std::vector<std::pair<SurfaceMesh::Face_index, SurfaceMesh::Face_index>> crossing;
    CGAL::Polygon_mesh_processing::self_intersections(sm, std::back_inserter(crossing),
                                                      CGAL::parameters::maximum_number(1));
    if (!crossing.empty()) {
      summary.check_seconds = seconds_since(start);
      const auto f = static_cast<std::size_t>(crossing.front().first);
      const auto g = static_cast<std::size_t>(crossing.front().second);
      std::ostringstream s;
      s << "the surface intersects itself: faces " << std::min(f, g) << " and " << std::max(f, g)
        << " cross";
      return finish(TetMesherStatus::kSelfIntersecting, s.str());
    }
    summary.check_seconds = seconds_since(start);
    meshing_start = Clock::now();

    // Mesh_3 draws its random initial surface points from the domain's generator; the default
    // generator is reset too in case some step falls back on it.
    CGAL::Random random(options.random_seed);
    CGAL::get_default_random() = CGAL::Random(options.random_seed);
    MeshDomain domain(sm, &random);
    if (options.protect_sharp_features) domain.detect_features(options.feature_angle_degrees);

    const std::optional<std::pair<TetMesherStatus, std::string>> failed =
        refine_and_optimise<Complex>(domain, options.protect_sharp_features, diagonal, options,
                                     result, meshing_start, &sm);
    if (failed) return finish(failed->first, failed->second);
  } catch (const std::exception& e) {
    summary.meshing_seconds = seconds_since(meshing_start);
    std::string what = e.what();
    std::replace(what.begin(), what.end(), '\n', ' ');
    return finish(TetMesherStatus::kCgalFailed, "CGAL threw: " + what);
  } catch (...) {
    summary.meshing_seconds = seconds_since(meshing_start);
    return finish(TetMesherStatus::kCgalFailed, "CGAL threw an unknown exception");
  }

  summary.num_vertices = result.mesh.vertices.rows();
  summary.num_tets = result.mesh.tets.rows();
  if (summary.num_tets == 0) {
    return finish(TetMesherStatus::kEmptyMesh,
                  "no tet lies inside the surface (is cell_size_fraction far too large?)");
  }
  summary.num_boundary_faces = count_boundary_faces(result.mesh);
  fill_quality(result.mesh, &summary);
  return finish(TetMesherStatus::kOk, "");
}

TetMesherResult make_tet_mesh_from_image(const std::vector<float>& values,
                                         const Eigen::Vector3i& size,
                                         const Eigen::Vector3d& spacing, double iso,
                                         const TetMesherOptions& options) {
  const auto start = Clock::now();
  TetMesherResult result;
  TetMesherSummary& summary = result.summary;
  const auto finish = [&](TetMesherStatus status, std::string message) {
    summary.status = status;
    summary.message = std::move(message);
    if (status != TetMesherStatus::kOk) result.mesh = TetMesh{};
    summary.seconds = seconds_since(start);
    return result;
  };
  if (const auto error = options.validate())
    return finish(TetMesherStatus::kInvalidOptions, *error);
  if ((size.array() <= 0).any() || values.size() != static_cast<std::size_t>(size.prod()) ||
      !(spacing.array() > 0).all() || !std::isfinite(iso)) {
    return finish(TetMesherStatus::kInvalidSurface,
                  "image: sizes, spacing or the number of values do not match");
  }
  // Sizes are relative to the bounding box of the voxels above iso.
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
  for (int k = 0; k < size.z(); ++k)
    for (int j = 0; j < size.y(); ++j)
      for (int i = 0; i < size.x(); ++i) {
        const float v = values[static_cast<std::size_t>(
            (static_cast<Eigen::Index>(k) * size.y() + j) * size.x() + i)];
        if (!std::isfinite(v))
          return finish(TetMesherStatus::kInvalidSurface, "image: a value is not finite");
        if (v > iso) {
          const Eigen::Vector3d p = Eigen::Vector3d(i, j, k).cwiseProduct(spacing);
          lo = lo.cwiseMin(p);
          hi = hi.cwiseMax(p);
        }
      }
  if (!(hi.x() >= lo.x()))
    return finish(TetMesherStatus::kEmptyMesh, "image: no voxel above the iso value");
  summary.bounding_box_diagonal = (hi - lo + spacing).norm();
  summary.check_seconds = seconds_since(start);
  const auto meshing_start = Clock::now();
  try {
    _image* raw =
        _createImage(static_cast<std::size_t>(size.x()), static_cast<std::size_t>(size.y()),
                     static_cast<std::size_t>(size.z()), 1, spacing.x(), spacing.y(), spacing.z(),
                     sizeof(float), WK_FLOAT, SGN_SIGNED);
    if (raw == nullptr)
      return finish(TetMesherStatus::kCgalFailed, "CGAL could not allocate the image");
    std::memcpy(raw->data, values.data(), values.size() * sizeof(float));
    const CGAL::Image_3 image(raw);
    CGAL::Random random(options.random_seed);
    CGAL::get_default_random() = CGAL::Random(options.random_seed);
    const ImageDomain domain = ImageDomain::create_gray_image_mesh_domain(
        image, static_cast<float>(iso), 0.0f, 1e-6, &random);
    const std::optional<std::pair<TetMesherStatus, std::string>> failed =
        refine_and_optimise<ImageComplex>(domain, false, summary.bounding_box_diagonal, options,
                                          result, meshing_start);
    if (failed) return finish(failed->first, failed->second);
  } catch (const std::exception& e) {
    summary.meshing_seconds = seconds_since(meshing_start);
    std::string what = e.what();
    std::replace(what.begin(), what.end(), '\n', ' ');
    return finish(TetMesherStatus::kCgalFailed, "CGAL threw: " + what);
  }
  summary.num_vertices = result.mesh.vertices.rows();
  summary.num_tets = result.mesh.tets.rows();
  if (summary.num_tets == 0) return finish(TetMesherStatus::kEmptyMesh, "no tet inside the region");
  summary.num_boundary_faces = count_boundary_faces(result.mesh);
  fill_quality(result.mesh, &summary);
  return finish(TetMesherStatus::kOk, "");
}

TetMeshQuality tet_mesh_quality(const TetMesh& mesh) {
  TetMeshQuality q;
  double min_angle = std::numeric_limits<double>::infinity(), max_angle = 0.0;
  double min_ratio = std::numeric_limits<double>::infinity(), sum_ratio = 0.0;
  for (Eigen::Index t = 0; t < mesh.tets.rows(); ++t) {
    std::array<Eigen::Vector3d, 4> p;
    for (int a = 0; a < 4; ++a) p[static_cast<std::size_t>(a)] = mesh.vertices.row(mesh.tets(t, a));
    for (const double angle : dihedral_angles(p)) {
      min_angle = std::min(min_angle, angle);
      max_angle = std::max(max_angle, angle);
    }
    const double ratio = radius_ratio(p);
    min_ratio = std::min(min_ratio, ratio);
    sum_ratio += ratio;
    const double volume = (p[1] - p[0]).dot((p[2] - p[0]).cross(p[3] - p[0])) / 6.0;
    q.volume += volume;
    q.inverted_tets += volume <= 0.0;
  }
  if (mesh.tets.rows() == 0) return q;
  q.min_dihedral_degrees = min_angle * 180.0 / kPi;
  q.max_dihedral_degrees = max_angle * 180.0 / kPi;
  q.min_radius_ratio = min_ratio;
  q.mean_radius_ratio = sum_ratio / static_cast<double>(mesh.tets.rows());
  return q;
}

}  // namespace sinew::offline
