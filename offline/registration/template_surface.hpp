#pragma once
/// ICP closest points on the template's own surface (seed 003 §3.4), for surface templates.
///
/// The tet mesh CGAL builds from a template surface only approximates it (its boundary facets
/// are within facet_distance_fraction·diagonal of it: about 1 mm on a 460 mm femur), while the
/// result the tool writes is the template surface carried by the deformation (its vertices are
/// material points of the tet mesh). Closest points on the tet boundary would fit the markers
/// with the wrong surface and leave that gap in the result; here the markers are fitted with the
/// surface that is written: each query finds the closest point on the deformed template surface
/// (triangle f, barycentric b), takes its template position X = Σ b_i X_i and embeds X in the tet
/// mesh with the same locator that embedded the surface vertices (the containing tet, or the
/// nearest one, extrapolated, when X is a little outside the mesh), so the marker moves with the
/// same piecewise-affine map as the written surface. Frozen within a Gauss–Newton iteration like
/// any ICP point. Template triangles longer than the tets are subdivided for the query (a large
/// flat triangle is not the image of the deformation between its corners).

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "offline/constraints/constraints.hpp"
#include "offline/io/surface_mesh_io.hpp"
#include "offline/registration/closest_point.hpp"
#include "offline/registration/surface_distance.hpp"

namespace sinew::offline {

class TemplateSurfaceClosestPoint final : public offline::ClosestSurfacePoint {
 public:
  /// tets and rest (3n dofs) of the tet mesh and its locator (which must outlive this object);
  /// triangles (#F by 3) of the template surface whose vertex i is the material point
  /// vertex_points[i].
  TemplateSurfaceClosestPoint(const common::TetIndices& tets, const Eigen::VectorXd& rest,
                              const offline::TetPointLocator& locator,
                              const Eigen::MatrixXi& triangles,
                              const std::vector<offline::EmbeddedPoint>& vertex_points);

  void update(const Eigen::Ref<const Eigen::VectorXd>& x) override;
  offline::EmbeddedPoint closest(const Eigen::Vector3d& query) const override;
  /// The surface normal at the closest point, whichever triangle holding it the search returned:
  /// off the surface (query − point)/distance, on it the mean normal of the triangles holding the
  /// point (a triangle's own inside it).
  Eigen::Vector3d normal(const Eigen::Vector3d& query) const override;

 private:
  common::TetIndices tets_;
  const offline::TetPointLocator* locator_;
  // The (refined) template surface: material points, their template positions, triangles.
  std::vector<offline::EmbeddedPoint> points_;
  Eigen::MatrixXd rest_positions_;
  Eigen::MatrixXi triangles_;
  std::optional<SurfaceDistance> deformed_;
  Eigen::VectorXd x_;                                        // positions of the last update
  std::vector<std::vector<Eigen::Index>> vertex_triangles_;  // triangles around each vertex
};

}  // namespace sinew::offline
