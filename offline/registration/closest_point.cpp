#include "offline/registration/closest_point.hpp"

#include <Eigen/Geometry>
#include <algorithm>

namespace sinew::offline {

void BoundaryClosestPoint::update(const Eigen::Ref<const Eigen::VectorXd>& x) {
  surface_->update(x);
  x_ = x;
  if (!vertex_faces_.empty()) return;
  const BoundarySurface& boundary = surface_->boundary();
  vertex_faces_.resize(static_cast<std::size_t>(boundary.num_mesh_vertices()));
  for (Eigen::Index f = 0; f < boundary.num_faces(); ++f) {
    for (int v : boundary.face(f).vertices) vertex_faces_[static_cast<std::size_t>(v)].push_back(f);
  }
}

Eigen::Vector3d BoundaryClosestPoint::normal(const Eigen::Vector3d& query) const {
  const SurfacePoint hit = surface_->query(query);
  if (!hit.ok() || x_.size() == 0) return Eigen::Vector3d::Zero();
  const BoundarySurface& boundary = surface_->boundary();
  const auto unit_normal = [&](Eigen::Index f) -> Eigen::Vector3d {
    const Eigen::Vector3d a = boundary.corner(f, 0, x_), b = boundary.corner(f, 1, x_),
                          c = boundary.corner(f, 2, x_);
    const Eigen::Vector3d n = (b - a).cross(c - a);
    const double length = n.norm();
    return length > 0.0 ? Eigen::Vector3d(n / length) : Eigen::Vector3d::Zero();
  };
  // A closest point on an edge or a corner is held by all the faces around it, and which of them
  // the AABB tree returns depends on the last bits of x. The returned face's normal made the
  // point-to-plane markers, and so Φ and the step, depend on the BLAS kernels: Fig. 4 at 5,184
  // tets, first ICP iteration, Φ 143,981 with OpenBLAS's Cooperlake kernels and 144,906 with
  // Haswell's from the same state (to 1e-12), and the runs ended 1.57 mm and 0.05 µm off the
  // markers. So the normal depends on the closest point alone: off the surface the gradient of
  // the distance, (query − point)/distance, which is ±the face normal when the point lies inside
  // a face; on the surface (within 1e-6 of the face's size, where that direction is noise) the
  // mean normal of the faces that hold the point.
  const Eigen::Vector3d a = boundary.corner(hit.face, 0, x_), b = boundary.corner(hit.face, 1, x_),
                        c = boundary.corner(hit.face, 2, x_);
  const double size = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
  if (hit.distance > 1e-6 * size) return Eigen::Vector3d((query - hit.point) / hit.distance);
  const BoundaryFace& face = boundary.face(hit.face);
  std::vector<int> support;  // the face's vertices the closest point depends on
  for (int i = 0; i < 3; ++i) {
    if (hit.barycentric[i] > 0.0) support.push_back(face.vertices[static_cast<std::size_t>(i)]);
  }
  if (support.size() == 3 || support.empty()) return unit_normal(hit.face);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (Eigen::Index f : vertex_faces_[static_cast<std::size_t>(support.front())]) {
    const auto& vertices = boundary.face(f).vertices;
    if (std::all_of(support.begin(), support.end(), [&](int v) {
          return std::find(vertices.begin(), vertices.end(), v) != vertices.end();
        })) {
      sum += unit_normal(f);
    }
  }
  const double length = sum.norm();
  return length > 0.0 ? Eigen::Vector3d(sum / length) : unit_normal(hit.face);
}

}  // namespace sinew::offline
