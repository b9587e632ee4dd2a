#pragma once
/// ICP closest points (seed 003 §3.4): the one interface the registration asks for the material
/// point of the deformed surface nearest a marker, and its implementation on the tet mesh's
/// boundary (a CGAL AABB tree, offline/meshing/surface_closest_point.hpp). The other
/// implementation, on the template's own surface, is TemplateSurfaceClosestPoint
/// (offline/registration/template_surface.hpp).

#include <Eigen/Core>
#include <vector>

#include "offline/constraints/constraints.hpp"
#include "offline/meshing/surface_closest_point.hpp"

namespace sinew::offline {

/// The material point of the deformed surface closest to a query, embedded in a tet of the mesh
/// (frozen barycentric coordinates for one ICP iteration).
class ClosestSurfacePoint {
 public:
  virtual ~ClosestSurfacePoint() = default;
  /// Re-targets the structure to the positions x (3n, vertex-major).
  virtual void update(const Eigen::Ref<const Eigen::VectorXd>& x) = 0;
  /// The material point closest to query on the current surface.
  virtual EmbeddedPoint closest(const Eigen::Vector3d& query) const = 0;
  /// A unit normal of the current surface at the point closest to query (either orientation);
  /// zero when the implementation has none (the marker then counts point to point).
  virtual Eigen::Vector3d normal(const Eigen::Vector3d& /*query*/) const {
    return Eigen::Vector3d::Zero();
  }
};

/// ClosestSurfacePoint on the CGAL AABB tree of offline/meshing/surface_closest_point.hpp.
class BoundaryClosestPoint final : public ClosestSurfacePoint {
 public:
  /// surface must outlive this object.
  explicit BoundaryClosestPoint(SurfaceClosestPoint& surface) : surface_(&surface) {}
  void update(const Eigen::Ref<const Eigen::VectorXd>& x) override;
  EmbeddedPoint closest(const Eigen::Vector3d& query) const override {
    return surface_->query(query).embedded;
  }
  /// The surface normal at the closest point, independent of which face holding it the tree
  /// returned: off the surface the distance's gradient (query − point)/distance, on it the mean
  /// normal of the faces holding the point (the face's own inside a face).
  Eigen::Vector3d normal(const Eigen::Vector3d& query) const override;

 private:
  SurfaceClosestPoint* surface_;
  Eigen::VectorXd x_;                                    // positions of the last update
  std::vector<std::vector<Eigen::Index>> vertex_faces_;  // boundary faces around each vertex
};

}  // namespace sinew::offline
