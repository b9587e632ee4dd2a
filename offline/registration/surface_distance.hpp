#pragma once
/// Distances between two triangle surfaces, for `sinew-register --truth FILE`: how far the
/// registered surface is from a known (or separately segmented) target surface. Point-to-surface
/// distances (closest point on any triangle, not vertex to vertex), so a result whose vertices
/// slid along the right surface scores as well as one that kept its correspondence.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "offline/io/surface_mesh_io.hpp"

namespace sinew::offline {

/// Closest-point distances to a fixed triangle surface, accelerated by a uniform grid of the
/// triangles' bounding boxes (about as many cells as triangles; a query visits rings of cells
/// around the point until no unvisited cell can hold a closer triangle).
class SurfaceDistance {
 public:
  /// surface: #V by 3 vertices and #F by 3 triangles (F ≥ 1; indices in range).
  explicit SurfaceDistance(const offline::io::SurfaceMesh& surface);

  /// Distance from p to the nearest point of the surface, in the surface's units.
  double distance(const Eigen::Vector3d& p) const { return closest(p).distance; }

  /// The nearest point of the surface to p: its triangle, barycentric coordinates (weights of
  /// the triangle's corners 0, 1, 2), position and distance.
  struct Closest {
    Eigen::Index triangle = 0;
    Eigen::Vector3d barycentric = Eigen::Vector3d::Constant(1.0 / 3.0);
    Eigen::Vector3d point = Eigen::Vector3d::Zero();
    double distance = 0.0;
  };
  Closest closest(const Eigen::Vector3d& p) const;

  /// Unit normal of triangle f (orientation as given; zero for a degenerate triangle).
  Eigen::Vector3d triangle_normal(Eigen::Index f) const;

 private:
  Eigen::Index cell_index(const Eigen::Vector3i& c) const {
    return (static_cast<Eigen::Index>(c.z()) * dims_.y() + c.y()) * dims_.x() + c.x();
  }

  offline::io::SurfaceMesh surface_;
  Eigen::Vector3d origin_;
  double cell_ = 1.0;
  Eigen::Vector3i dims_;
  std::vector<int> cell_start_;  // CSR: triangles of cell i are cell_triangles_[start[i]..[i+1])
  std::vector<int> cell_triangles_;
};

/// Distances from every vertex of one surface to the other surface.
struct SurfaceDistanceStats {
  double mean = 0.0;
  double max = 0.0;
};

/// from's vertices to the surface to (one-sided).
SurfaceDistanceStats vertex_to_surface_distances(const offline::io::SurfaceMesh& from,
                                                 const offline::io::SurfaceMesh& to);

/// `samples` points spread uniformly by area over a surface (a triangle drawn with probability
/// proportional to its area, then a uniform point in it), as #samples by 3. Deterministic for a
/// seed on every platform (std::mt19937_64's raw output, mapped to [0, 1) here, not through the
/// library's distributions).
Eigen::MatrixXd area_uniform_samples(const offline::io::SurfaceMesh& surface, int samples,
                                     std::uint64_t seed);

/// The symmetric surface distance of two surfaces as the vertebra peers are scored
/// (../shared/data/vertebrae, issue 18): `samples` area-uniform points on each surface, the exact
/// point-to-triangle distance of each to the other surface; `mean` is the mean over both sets.
/// Unlike vertex_to_surface_distances it does not weigh a surface by where its mesh is dense.
struct SymmetricSurfaceDistance {
  SurfaceDistanceStats a_to_b;
  SurfaceDistanceStats b_to_a;
  double mean = 0.0;
  int samples = 0;
};
SymmetricSurfaceDistance sampled_surface_distance(const offline::io::SurfaceMesh& a,
                                                  const offline::io::SurfaceMesh& b,
                                                  int samples = 30000, std::uint64_t seed = 1);

}  // namespace sinew::offline
