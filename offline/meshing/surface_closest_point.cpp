#include "offline/meshing/surface_closest_point.hpp"

// CGAL is confined to this translation unit (and meshing/tet_mesher.cpp).
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <tuple>
#include <utility>

namespace sinew::offline {
namespace {

/// Outward faces of a right-handed tet (v0, v1, v2, v3), indexed by the opposite local vertex:
/// the normal (b − a) × (c − a) of each points away from the opposite vertex.
constexpr int kOutwardFaces[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

}  // namespace

// ------------------------------------------------------------------------------------------------
// BoundarySurface
// ------------------------------------------------------------------------------------------------

const char* to_string(BoundaryStatus status) {
  switch (status) {
    case BoundaryStatus::kOk:
      return "ok";
    case BoundaryStatus::kInvalidMesh:
      return "tet references a vertex out of range";
    case BoundaryStatus::kRepeatedVertex:
      return "tet uses a vertex twice";
    case BoundaryStatus::kNonManifold:
      return "face shared by more than two tets";
    case BoundaryStatus::kEmpty:
      return "mesh has no tets";
  }
  return "unknown";
}

std::string BoundaryCheck::message() const {
  std::ostringstream s;
  s << to_string(status);
  if (tet) s << " (tet " << *tet << ")";
  return s.str();
}

std::optional<BoundarySurface> BoundarySurface::extract(Eigen::Index num_vertices,
                                                        const common::TetIndices& tets,
                                                        BoundaryCheck* check) {
  const auto fail = [&](BoundaryStatus status, std::optional<Eigen::Index> tet) {
    if (check) *check = BoundaryCheck{status, tet};
    return std::nullopt;
  };
  if (num_vertices < 0) return fail(BoundaryStatus::kInvalidMesh, std::nullopt);
  if (tets.rows() == 0) return fail(BoundaryStatus::kEmpty, std::nullopt);
  for (Eigen::Index t = 0; t < tets.rows(); ++t) {
    for (int a = 0; a < 4; ++a) {
      if (tets(t, a) < 0 || tets(t, a) >= num_vertices)
        return fail(BoundaryStatus::kInvalidMesh, t);
      for (int b = 0; b < a; ++b) {
        if (tets(t, a) == tets(t, b)) return fail(BoundaryStatus::kRepeatedVertex, t);
      }
    }
  }

  // Every (tet, local face) keyed by its sorted vertex triple; runs of length 1 are the boundary.
  struct TetFace {
    std::array<int, 3> key;
    Eigen::Index tet;
    int opposite;
  };
  std::vector<TetFace> all;
  all.reserve(static_cast<std::size_t>(4 * tets.rows()));
  for (Eigen::Index t = 0; t < tets.rows(); ++t) {
    for (int opposite = 0; opposite < 4; ++opposite) {
      std::array<int, 3> key{};
      for (int i = 0; i < 3; ++i)
        key[static_cast<std::size_t>(i)] = tets(t, kOutwardFaces[opposite][i]);
      std::sort(key.begin(), key.end());
      all.push_back({key, t, opposite});
    }
  }
  std::sort(all.begin(), all.end(), [](const TetFace& x, const TetFace& y) {
    return std::tie(x.key, x.tet, x.opposite) < std::tie(y.key, y.tet, y.opposite);
  });
  std::vector<std::pair<Eigen::Index, int>> boundary;  // (tet, opposite)
  for (std::size_t i = 0; i < all.size();) {
    std::size_t j = i;
    while (j < all.size() && all[j].key == all[i].key) ++j;
    if (j - i > 2) return fail(BoundaryStatus::kNonManifold, all[i + 2].tet);
    if (j - i == 1) boundary.emplace_back(all[i].tet, all[i].opposite);
    i = j;
  }
  std::sort(boundary.begin(), boundary.end());

  BoundarySurface surface;
  surface.num_vertices_ = num_vertices;
  surface.faces_.reserve(boundary.size());
  surface.triangles_.resize(static_cast<Eigen::Index>(boundary.size()), 3);
  for (const auto& [t, opposite] : boundary) {
    BoundaryFace face;
    face.tet = t;
    face.opposite_slot = opposite;
    for (int i = 0; i < 3; ++i) {
      const int slot = kOutwardFaces[opposite][i];
      face.slots[static_cast<std::size_t>(i)] = slot;
      face.vertices[static_cast<std::size_t>(i)] = tets(t, slot);
      surface.triangles_(static_cast<Eigen::Index>(surface.faces_.size()), i) = tets(t, slot);
      surface.boundary_vertices_.push_back(tets(t, slot));
    }
    surface.faces_.push_back(face);
  }
  auto& bv = surface.boundary_vertices_;
  std::sort(bv.begin(), bv.end());
  bv.erase(std::unique(bv.begin(), bv.end()), bv.end());
  if (check) *check = BoundaryCheck{};
  return surface;
}

EmbeddedPoint BoundarySurface::embed(Eigen::Index f, const Eigen::Vector3d& barycentric) const {
  const BoundaryFace& bf = face(f);
  EmbeddedPoint p;
  p.tet = bf.tet;
  p.weights.setZero();
  for (int i = 0; i < 3; ++i) p.weights(bf.slots[static_cast<std::size_t>(i)]) = barycentric(i);
  return p;
}

Eigen::Vector3d BoundarySurface::corner(Eigen::Index f, int i,
                                        const Eigen::Ref<const Eigen::VectorXd>& x) const {
  return x.segment<3>(3 * static_cast<Eigen::Index>(face(f).vertices[static_cast<std::size_t>(i)]));
}

// ------------------------------------------------------------------------------------------------
// Point-triangle closest point (Ericson, Real-Time Collision Detection §5.1.5: Voronoi regions of
// the vertices, edges and face), with a fallback to the edges for degenerate triangles.
// ------------------------------------------------------------------------------------------------

namespace {

TriangleClosestPoint on_segment(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                const Eigen::Vector3d& b, int ia, int ib) {
  const Eigen::Vector3d ab = b - a;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  TriangleClosestPoint r;
  r.barycentric.setZero();
  r.barycentric(ia) = 1.0 - t;
  r.barycentric(ib) = t;
  r.point = a + t * ab;
  return r;
}

}  // namespace

TriangleClosestPoint closest_point_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                               const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  TriangleClosestPoint r;
  const auto at = [&r](const Eigen::Vector3d& q, double u, double v, double w) {
    r.point = q;
    r.barycentric << u, v, w;
    return r;
  };
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return at(a, 1.0, 0.0, 0.0);
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return at(b, 0.0, 1.0, 0.0);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    const double v = d1 / (d1 - d3);
    return at(a + v * ab, 1.0 - v, v, 0.0);
  }
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return at(c, 0.0, 0.0, 1.0);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    const double w = d2 / (d2 - d6);
    return at(a + w * ac, 1.0 - w, 0.0, w);
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return at(b + w * (c - b), 0.0, 1.0 - w, w);
  }
  const double sum = va + vb + vc;  // = ‖ab × ac‖², 0 for a degenerate triangle
  if (!(sum > std::numeric_limits<double>::min()) || !std::isfinite(sum)) {
    TriangleClosestPoint best = on_segment(p, a, b, 0, 1);
    for (const auto& candidate : {on_segment(p, b, c, 1, 2), on_segment(p, c, a, 2, 0)}) {
      if ((candidate.point - p).squaredNorm() < (best.point - p).squaredNorm()) best = candidate;
    }
    return best;
  }
  const double v = vb / sum, w = vc / sum;
  return at(a + v * ab + w * ac, 1.0 - v - w, v, w);
}

// ------------------------------------------------------------------------------------------------
// SurfaceClosestPoint
// ------------------------------------------------------------------------------------------------

const char* to_string(SurfaceQueryStatus status) {
  switch (status) {
    case SurfaceQueryStatus::kOk:
      return "ok";
    case SurfaceQueryStatus::kNotUpdated:
      return "no positions (update() has not succeeded)";
    case SurfaceQueryStatus::kNonFinite:
      return "query point is not finite";
    case SurfaceQueryStatus::kWrongShape:
      return "points are not #P by 3";
  }
  return "unknown";
}

const char* to_string(SurfaceUpdateStatus status) {
  switch (status) {
    case SurfaceUpdateStatus::kOk:
      return "ok";
    case SurfaceUpdateStatus::kWrongSize:
      return "x does not have 3n entries";
    case SurfaceUpdateStatus::kNonFinite:
      return "a boundary vertex position is not finite";
  }
  return "unknown";
}

struct SurfaceClosestPoint::Impl {
  using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
  using Triangles = std::vector<Kernel::Triangle_3>;
  using Primitive = CGAL::AABB_triangle_primitive<Kernel, Triangles::const_iterator>;
  using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, Primitive>>;

  Impl(BoundarySurface b, common::TetIndices t) : boundary(std::move(b)), tets(std::move(t)) {}

  BoundarySurface boundary;
  common::TetIndices tets;
  Eigen::VectorXd x;    // positions of the last successful update
  Triangles triangles;  // one per boundary face, in face order (primitive id - begin = face)
  Tree tree;
  bool updated = false;
};

SurfaceClosestPoint::SurfaceClosestPoint(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
SurfaceClosestPoint::SurfaceClosestPoint(SurfaceClosestPoint&&) noexcept = default;
SurfaceClosestPoint& SurfaceClosestPoint::operator=(SurfaceClosestPoint&&) noexcept = default;
SurfaceClosestPoint::~SurfaceClosestPoint() = default;

std::optional<SurfaceClosestPoint> SurfaceClosestPoint::create(Eigen::Index num_vertices,
                                                               const common::TetIndices& tets,
                                                               BoundaryCheck* check) {
  auto boundary = BoundarySurface::extract(num_vertices, tets, check);
  if (!boundary) return std::nullopt;
  auto impl = std::make_unique<Impl>(std::move(*boundary), tets);
  impl->triangles.resize(static_cast<std::size_t>(impl->boundary.num_faces()));
  return SurfaceClosestPoint(std::move(impl));
}

const BoundarySurface& SurfaceClosestPoint::boundary() const {
  return impl_->boundary;
}
const common::TetIndices& SurfaceClosestPoint::tets() const {
  return impl_->tets;
}
bool SurfaceClosestPoint::updated() const {
  return impl_->updated;
}

SurfaceUpdateStatus SurfaceClosestPoint::update(const Eigen::Ref<const Eigen::VectorXd>& x) {
  Impl& m = *impl_;
  m.updated = false;
  if (x.size() != 3 * m.boundary.num_mesh_vertices()) return SurfaceUpdateStatus::kWrongSize;
  for (const int v : m.boundary.vertices()) {
    if (!x.segment<3>(3 * static_cast<Eigen::Index>(v)).allFinite())
      return SurfaceUpdateStatus::kNonFinite;
  }
  m.x = x;
  const auto point = [&m](int v) {
    const auto p = m.x.segment<3>(3 * static_cast<Eigen::Index>(v));
    return Impl::Kernel::Point_3(p(0), p(1), p(2));
  };
  for (std::size_t f = 0; f < m.triangles.size(); ++f) {
    const auto& v = m.boundary.faces()[f].vertices;
    m.triangles[f] = Impl::Kernel::Triangle_3(point(v[0]), point(v[1]), point(v[2]));
  }
  // The primitives refer to the triangles by iterator and read them on demand, so the hierarchy
  // (boxes) and the distance-query k-d tree are rebuilt over the same storage.
  m.tree.rebuild(m.triangles.cbegin(), m.triangles.cend());
  m.tree.accelerate_distance_queries();
  m.updated = true;
  return SurfaceUpdateStatus::kOk;
}

SurfacePoint SurfaceClosestPoint::query(const Eigen::Vector3d& point) const {
  const Impl& m = *impl_;
  SurfacePoint r;
  if (!point.allFinite()) {
    r.status = SurfaceQueryStatus::kNonFinite;
    return r;
  }
  if (!m.updated) {
    r.status = SurfaceQueryStatus::kNotUpdated;
    return r;
  }
  const auto hit =
      m.tree.closest_point_and_primitive(Impl::Kernel::Point_3(point(0), point(1), point(2)));
  const Eigen::Index f = static_cast<Eigen::Index>(hit.second - m.triangles.cbegin());
  // The tree finds the face; the point and its barycentric coordinates are recomputed on that
  // face so that the embedded point reproduces it exactly (up to round-off).
  const TriangleClosestPoint c =
      closest_point_on_triangle(point, m.boundary.corner(f, 0, m.x), m.boundary.corner(f, 1, m.x),
                                m.boundary.corner(f, 2, m.x));
  r.status = SurfaceQueryStatus::kOk;
  r.point = c.point;
  r.distance = (c.point - point).norm();
  r.face = f;
  r.barycentric = c.barycentric;
  r.embedded = m.boundary.embed(f, c.barycentric);
  return r;
}

void SurfaceClosestPoint::query(const Eigen::Ref<const Eigen::MatrixXd>& points,
                                std::vector<SurfacePoint>* out) const {
  out->resize(static_cast<std::size_t>(points.rows()));
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    auto& r = (*out)[static_cast<std::size_t>(i)];
    if (points.cols() != 3) {
      r = SurfacePoint{};
      r.status = SurfaceQueryStatus::kWrongShape;
    } else {
      r = query(Eigen::Vector3d(points.row(i).transpose()));
    }
  }
}

}  // namespace sinew::offline
