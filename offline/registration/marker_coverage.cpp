#include "offline/registration/marker_coverage.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

namespace sinew::offline {
namespace {

// Points sorted by x, for queries that only need the points within a radius or the nearest one:
// a query walks outwards from its own x and stops once the x gap alone is too large.
struct SweepIndex {
  std::vector<Eigen::Vector3d> points;
  std::vector<std::size_t> original;  // index into the input of each sorted point

  explicit SweepIndex(const std::vector<Eigen::Vector3d>& input) : original(input.size()) {
    for (std::size_t i = 0; i < input.size(); ++i) original[i] = i;
    std::sort(original.begin(), original.end(),
              [&input](std::size_t a, std::size_t b) { return input[a].x() < input[b].x(); });
    points.reserve(input.size());
    for (std::size_t i : original) points.push_back(input[i]);
  }

  std::size_t start(double x) const {
    return static_cast<std::size_t>(
        std::lower_bound(points.begin(), points.end(), x,
                         [](const Eigen::Vector3d& p, double v) { return p.x() < v; }) -
        points.begin());
  }

  // Squared distance to the nearest point and its sorted index (+∞ and size() without points).
  std::pair<double, std::size_t> nearest(const Eigen::Vector3d& q) const {
    double best2 = std::numeric_limits<double>::infinity();
    std::size_t best = points.size();
    const std::size_t s = start(q.x());
    const auto visit = [&](std::size_t k) {
      const double dx = points[k].x() - q.x();
      if (dx * dx >= best2) return false;
      const double d2 = (points[k] - q).squaredNorm();
      if (d2 < best2) {
        best2 = d2;
        best = k;
      }
      return true;
    };
    for (std::size_t k = s; k < points.size() && visit(k); ++k) {
    }
    for (std::size_t k = s; k > 0 && visit(k - 1); --k) {
    }
    return {best2, best};
  }

  // Calls f(sorted index, squared distance) for every point within radius of q.
  template <class F>
  void within(const Eigen::Vector3d& q, double radius, F&& f) const {
    const double r2 = radius * radius;
    for (std::size_t k = start(q.x() - radius); k < points.size(); ++k) {
      if (points[k].x() > q.x() + radius) break;
      const double d2 = (points[k] - q).squaredNorm();
      if (d2 <= r2) f(k, d2);
    }
  }
};

}  // namespace

MarkerCoverage marker_coverage(const Eigen::MatrixXd& vertices, const Eigen::MatrixXi& triangles,
                               const std::vector<Eigen::Vector3d>& pinned,
                               const std::vector<Eigen::Vector3d>& sliding, std::size_t markers,
                               const MarkerCoverageOptions& options) {
  MarkerCoverage c;
  const Eigen::Index nv = vertices.rows();
  c.distance.setConstant(nv, std::numeric_limits<double>::infinity());
  c.pinning.setZero(nv);

  // Vertex areas (a third of each triangle's) and area-weighted vertex normals.
  Eigen::VectorXd vertex_area = Eigen::VectorXd::Zero(nv);
  Eigen::MatrixXd normals = Eigen::MatrixXd::Zero(nv, 3);
  std::vector<bool> on_surface(static_cast<std::size_t>(nv), false);
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    const Eigen::Vector3d a = vertices.row(triangles(f, 0)).transpose();
    const Eigen::Vector3d b = vertices.row(triangles(f, 1)).transpose();
    const Eigen::Vector3d d = vertices.row(triangles(f, 2)).transpose();
    const Eigen::Vector3d doubled = (b - a).cross(d - a);  // 2 · area · unit normal
    c.area += 0.5 * doubled.norm();
    for (int k = 0; k < 3; ++k) {
      vertex_area[triangles(f, k)] += doubled.norm() / 6.0;
      normals.row(triangles(f, k)) += doubled.transpose();
      on_surface[static_cast<std::size_t>(triangles(f, k))] = true;
    }
  }
  const std::size_t count = markers > 0 ? markers : pinned.size() + sliding.size();
  if (count > 0) c.nominal_spacing = std::sqrt(c.area / static_cast<double>(count));
  const double k = options.uncovered_spacings;
  c.pinning_threshold = std::exp(-0.5 * k * k);

  // Each ICP marker's normal: that of the surface vertex nearest to it.
  std::vector<Eigen::Vector3d> surface_vertices;
  std::vector<Eigen::Index> surface_index;
  for (Eigen::Index v = 0; v < nv; ++v) {
    if (!on_surface[static_cast<std::size_t>(v)]) continue;
    surface_vertices.push_back(vertices.row(v).transpose());
    surface_index.push_back(v);
  }
  const SweepIndex surface(surface_vertices);
  std::vector<Eigen::Vector3d> sliding_normal(sliding.size(), Eigen::Vector3d::Zero());
  for (std::size_t i = 0; i < sliding.size(); ++i) {
    const std::size_t s = surface.nearest(sliding[i]).second;
    if (s == surface.points.size()) continue;
    const Eigen::Vector3d n = normals.row(surface_index[surface.original[s]]).transpose();
    if (n.norm() > 0) sliding_normal[i] = n.normalized();
  }

  std::vector<Eigen::Vector3d> all(pinned);
  all.insert(all.end(), sliding.begin(), sliding.end());
  const SweepIndex points(all);
  // Weights below exp(−18) (6 spacings) are left out.
  const double h = c.nominal_spacing, radius = 6.0 * h;
  const double limit = k * h;
  double uncovered = 0.0, weak = 0.0;
  for (Eigen::Index v = 0; v < nv; ++v) {
    const Eigen::Vector3d p = vertices.row(v).transpose();
    c.distance[v] = std::sqrt(points.nearest(p).first);
    const double normal_length = normals.row(v).norm();
    if (h > 0 && normal_length > 0) {
      const Eigen::Vector3d np = normals.row(v).transpose() / normal_length;
      double pin = 0.0;
      points.within(p, radius, [&](std::size_t s, double d2) {
        const double w = std::exp(-0.5 * d2 / (h * h));
        const std::size_t i = points.original[s];
        if (i < pinned.size()) {
          pin += w;
        } else {
          const double along = np.dot(sliding_normal[i - pinned.size()]);
          pin += w * along * along;
        }
      });
      c.pinning[v] = pin;
    }

    if (!on_surface[static_cast<std::size_t>(v)]) continue;
    if (c.farthest_vertex < 0 || c.distance[v] > c.max_distance) {
      c.max_distance = c.distance[v];
      c.farthest_vertex = v;
    }
    if (c.weakest_vertex < 0 || c.pinning[v] < c.min_pinning) {
      c.min_pinning = c.pinning[v];
      c.weakest_vertex = v;
    }
    if (c.distance[v] > limit) uncovered += vertex_area[v];
    if (c.pinning[v] < c.pinning_threshold) weak += vertex_area[v];
  }
  if (c.area > 0.0) {
    c.uncovered_area_fraction = uncovered / c.area;
    c.weakly_pinned_area_fraction = weak / c.area;
  }
  return c;
}

}  // namespace sinew::offline
