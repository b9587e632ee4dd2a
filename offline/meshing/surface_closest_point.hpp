#pragma once
/// Closest points on the deformed boundary surface of a tet mesh: the ICP markers of seed 003
/// (§3.4, appendix F). Each Gauss-Newton iteration finds, for every scan marker, the closest point
/// on the current (deformed) boundary surface and freezes its barycentric coordinates in the tet
/// owning that boundary face for the iteration; the marker is then a point constraint
/// (offline/constraints/constraints.hpp) pulled towards the scan point.
///
/// BoundarySurface: the faces of the tet mesh that belong to exactly one tet, oriented outward,
/// each remembering its tet and the local vertex slots, so a point (u, v, w) on the face becomes
/// an EmbeddedPoint of that tet (weights u, v, w at the face's slots, 0 at the opposite one).
///
/// SurfaceClosestPoint: the boundary plus a CGAL AABB tree over the current triangles, rebuilt by
/// update(x). CGAL stays inside surface_closest_point.cpp (pimpl); this header is Eigen only.

#include <Eigen/Core>
#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/fem/sparse_assembly.hpp"
#include "offline/constraints/constraints.hpp"

namespace sinew::offline {

/// A boundary face of a tet mesh.
struct BoundaryFace {
  Eigen::Index tet = 0;           ///< the one tet owning the face (row of tets)
  std::array<int, 3> vertices{};  ///< mesh vertex indices, counter-clockwise seen from outside
  std::array<int, 3> slots{};     ///< local slots (0..3) of vertices[i] in the tet's row
  int opposite_slot = 0;          ///< slot of the tet vertex not on the face
};

enum class BoundaryStatus {
  kOk,
  kInvalidMesh,     ///< num_vertices < 0, or a tet references a vertex outside [0, num_vertices)
  kRepeatedVertex,  ///< a tet uses a vertex twice
  kNonManifold,     ///< a face is shared by more than two tets
  kEmpty,           ///< no tets
};

const char* to_string(BoundaryStatus status);

/// Outcome of building a boundary; tet names the first offending tet when there is one.
struct BoundaryCheck {
  BoundaryStatus status = BoundaryStatus::kOk;
  std::optional<Eigen::Index> tet;
  bool ok() const { return status == BoundaryStatus::kOk; }
  /// One line: the status and, if any, the offending tet.
  std::string message() const;
};

/// The boundary surface of a tet mesh (topology only).
class BoundarySurface {
 public:
  /// Faces of tets (#T by 4, right-handed: positive signed volume) that belong to exactly one
  /// tet, in order of (tet, local face). Orientation is outward provided the tets are
  /// right-handed (see common::check_tet_mesh). std::nullopt when the mesh is invalid; check (if
  /// not null) then says why.
  static std::optional<BoundarySurface> extract(Eigen::Index num_vertices,
                                                const common::TetIndices& tets,
                                                BoundaryCheck* check = nullptr);

  Eigen::Index num_faces() const { return static_cast<Eigen::Index>(faces_.size()); }
  Eigen::Index num_mesh_vertices() const { return num_vertices_; }
  const std::vector<BoundaryFace>& faces() const { return faces_; }
  const BoundaryFace& face(Eigen::Index f) const { return faces_[static_cast<std::size_t>(f)]; }

  /// The boundary as a triangle list, #F by 3 vertex indices into the tet mesh, outward
  /// (counter-clockwise from outside), for writing surfaces.
  const Eigen::Matrix<int, Eigen::Dynamic, 3>& triangles() const { return triangles_; }
  /// Sorted mesh indices of the vertices on the boundary.
  const std::vector<int>& vertices() const { return boundary_vertices_; }

  /// The material point at triangle barycentric coordinates (u, v, w) (weights of
  /// face(f).vertices[0..2], summing to 1) as an EmbeddedPoint of face(f).tet.
  EmbeddedPoint embed(Eigen::Index f, const Eigen::Vector3d& barycentric) const;

  /// Position of face f's corner i (0..2) in the dof vector x (3n, vertex-major, metres).
  Eigen::Vector3d corner(Eigen::Index f, int i, const Eigen::Ref<const Eigen::VectorXd>& x) const;

 private:
  BoundarySurface() = default;

  Eigen::Index num_vertices_ = 0;
  std::vector<BoundaryFace> faces_;
  Eigen::Matrix<int, Eigen::Dynamic, 3> triangles_;
  std::vector<int> boundary_vertices_;
};

/// Closest point on a triangle (a, b, c) to p, with its barycentric coordinates (weights of a, b,
/// c; all in [0, 1], summing to 1). Robust for degenerate triangles (falls back to the edges).
struct TriangleClosestPoint {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d barycentric = Eigen::Vector3d::Constant(1.0 / 3.0);
};
TriangleClosestPoint closest_point_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                               const Eigen::Vector3d& b, const Eigen::Vector3d& c);

enum class SurfaceQueryStatus {
  kOk,
  kNotUpdated,  ///< update() has not succeeded since construction (or the last failed update)
  kNonFinite,   ///< the query point has NaN or infinite coordinates
  kWrongShape,  ///< (batch query) the points matrix does not have 3 columns
};

const char* to_string(SurfaceQueryStatus status);

/// Answer of one closest-point query.
struct SurfacePoint {
  SurfaceQueryStatus status = SurfaceQueryStatus::kNotUpdated;
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  ///< closest point on the surface, metres
  double distance = 0.0;                            ///< from the query point, metres
  Eigen::Index face = 0;                            ///< boundary face index (BoundarySurface)
  Eigen::Vector3d barycentric = Eigen::Vector3d::Constant(1.0 / 3.0);  ///< on that face
  /// The closest point as a material point of face's tet: embedded_position(tets, embedded, x)
  /// reproduces point for the x of the last update().
  EmbeddedPoint embedded;

  bool ok() const { return status == SurfaceQueryStatus::kOk; }
};

enum class SurfaceUpdateStatus {
  kOk,
  kWrongSize,  ///< x does not have 3·num_vertices entries
  kNonFinite,  ///< a boundary vertex of x is NaN or infinite
};

const char* to_string(SurfaceUpdateStatus status);

/// Closest-point queries against the boundary surface of a deforming tet mesh. Built once from
/// the topology; update(x) takes the current positions (rebuilding the AABB tree, O(F log F));
/// each query is O(log F) on average. Movable, not copyable. Queries are const and may run
/// concurrently from several threads between updates.
class SurfaceClosestPoint {
 public:
  /// num_vertices: n of the mesh; tets: #T by 4, right-handed. std::nullopt when the mesh is
  /// invalid; check (if not null) then says why.
  static std::optional<SurfaceClosestPoint> create(Eigen::Index num_vertices,
                                                   const common::TetIndices& tets,
                                                   BoundaryCheck* check = nullptr);

  SurfaceClosestPoint(SurfaceClosestPoint&&) noexcept;
  SurfaceClosestPoint& operator=(SurfaceClosestPoint&&) noexcept;
  SurfaceClosestPoint(const SurfaceClosestPoint&) = delete;
  SurfaceClosestPoint& operator=(const SurfaceClosestPoint&) = delete;
  ~SurfaceClosestPoint();

  const BoundarySurface& boundary() const;
  const common::TetIndices& tets() const;

  /// Takes the current positions x (3n, vertex-major, metres) and rebuilds the tree over the
  /// boundary triangles. On failure the previous positions are discarded and queries answer
  /// kNotUpdated until the next successful update.
  SurfaceUpdateStatus update(const Eigen::Ref<const Eigen::VectorXd>& x);
  bool updated() const;

  /// Closest point on the boundary surface (positions of the last update) to point (metres).
  SurfacePoint query(const Eigen::Vector3d& point) const;
  /// query() for each row of points (#P by 3, metres); out is resized to #P (every entry
  /// kWrongShape when points does not have 3 columns).
  void query(const Eigen::Ref<const Eigen::MatrixXd>& points, std::vector<SurfacePoint>* out) const;

 private:
  struct Impl;
  explicit SurfaceClosestPoint(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace sinew::offline
