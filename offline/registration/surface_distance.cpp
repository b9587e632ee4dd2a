#include "offline/registration/surface_distance.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "offline/meshing/surface_closest_point.hpp"

namespace sinew::offline {

SurfaceDistance::SurfaceDistance(const offline::io::SurfaceMesh& surface) : surface_(surface) {
  const Eigen::Index num_triangles = surface_.triangles.rows();
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (Eigen::Index f = 0; f < num_triangles; ++f) {
    for (int k = 0; k < 3; ++k) {
      lo = lo.cwiseMin(surface_.vertices.row(surface_.triangles(f, k)).transpose());
      hi = hi.cwiseMax(surface_.vertices.row(surface_.triangles(f, k)).transpose());
    }
  }
  // About one cell per triangle over the bounding box (a thin surface fills few of them).
  const Eigen::Vector3d extent = (hi - lo).cwiseMax(1e-12 * (hi - lo).norm() + 1e-300);
  cell_ = std::cbrt(extent.prod() / static_cast<double>(std::max<Eigen::Index>(num_triangles, 1)));
  cell_ = std::max(cell_, extent.maxCoeff() / 128);
  origin_ = lo;
  for (int i = 0; i < 3; ++i)
    dims_[i] = std::max(1, static_cast<int>(std::ceil(extent[i] / cell_)));

  auto cell_of = [&](const Eigen::Vector3d& p) {
    Eigen::Vector3i c;
    for (int i = 0; i < 3; ++i)
      c[i] = std::clamp(static_cast<int>(std::floor((p[i] - origin_[i]) / cell_)), 0, dims_[i] - 1);
    return c;
  };
  const Eigen::Index num_cells = static_cast<Eigen::Index>(dims_.x()) * dims_.y() * dims_.z();
  std::vector<std::pair<Eigen::Vector3i, Eigen::Vector3i>> ranges;
  ranges.reserve(static_cast<std::size_t>(num_triangles));
  cell_start_.assign(static_cast<std::size_t>(num_cells) + 1, 0);
  for (Eigen::Index f = 0; f < num_triangles; ++f) {
    Eigen::Vector3d a = surface_.vertices.row(surface_.triangles(f, 0)).transpose(), b = a;
    for (int k = 1; k < 3; ++k) {
      a = a.cwiseMin(surface_.vertices.row(surface_.triangles(f, k)).transpose());
      b = b.cwiseMax(surface_.vertices.row(surface_.triangles(f, k)).transpose());
    }
    ranges.emplace_back(cell_of(a), cell_of(b));
  }
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<int> fill;
    if (pass == 1) {
      for (std::size_t i = 1; i < cell_start_.size(); ++i) cell_start_[i] += cell_start_[i - 1];
      cell_triangles_.resize(static_cast<std::size_t>(cell_start_.back()));
      fill.assign(cell_start_.begin(), cell_start_.end() - 1);
    }
    for (std::size_t f = 0; f < ranges.size(); ++f) {
      const auto& [from, to] = ranges[f];
      for (int z = from.z(); z <= to.z(); ++z)
        for (int y = from.y(); y <= to.y(); ++y)
          for (int x = from.x(); x <= to.x(); ++x) {
            const auto i = static_cast<std::size_t>(cell_index({x, y, z}));
            if (pass == 0)
              ++cell_start_[i + 1];
            else
              cell_triangles_[static_cast<std::size_t>(fill[i]++)] = static_cast<int>(f);
          }
    }
  }
}

SurfaceDistance::Closest SurfaceDistance::closest(const Eigen::Vector3d& p) const {
  Eigen::Vector3i c;
  for (int i = 0; i < 3; ++i)
    c[i] = std::clamp(static_cast<int>(std::floor((p[i] - origin_[i]) / cell_)), 0, dims_[i] - 1);
  double best = std::numeric_limits<double>::infinity();
  Closest result;
  const int max_ring = dims_.maxCoeff();
  // Every point of a cell outside ring k of p's (clamped) cell is at least k cells from p: for p
  // outside the grid, clamping onto the grid's box only shortens distances to points inside it.
  for (int k = 0; k <= max_ring; ++k) {
    for (int z = c.z() - k; z <= c.z() + k; ++z) {
      if (z < 0 || z >= dims_.z()) continue;
      for (int y = c.y() - k; y <= c.y() + k; ++y) {
        if (y < 0 || y >= dims_.y()) continue;
        const bool shell = std::abs(z - c.z()) == k || std::abs(y - c.y()) == k;
        const int step = shell ? 1 : 2 * k;  // interior rows: only the two ends are on the ring
        for (int x = c.x() - k; x <= c.x() + k; x += std::max(step, 1)) {
          if (x < 0 || x >= dims_.x()) continue;
          const auto i = static_cast<std::size_t>(cell_index({x, y, z}));
          for (int j = cell_start_[i]; j < cell_start_[i + 1]; ++j) {
            const int f = cell_triangles_[static_cast<std::size_t>(j)];
            const auto q = offline::closest_point_on_triangle(
                p, surface_.vertices.row(surface_.triangles(f, 0)).transpose(),
                surface_.vertices.row(surface_.triangles(f, 1)).transpose(),
                surface_.vertices.row(surface_.triangles(f, 2)).transpose());
            const double d = (q.point - p).norm();
            if (d < best) {
              best = d;
              result = Closest{f, q.barycentric, q.point, d};
            }
          }
        }
      }
    }
    if (best <= k * cell_) break;
  }
  return result;
}

SurfaceDistanceStats vertex_to_surface_distances(const offline::io::SurfaceMesh& from,
                                                 const offline::io::SurfaceMesh& to) {
  const SurfaceDistance query(to);
  SurfaceDistanceStats stats;
  for (Eigen::Index v = 0; v < from.vertices.rows(); ++v) {
    const double d = query.distance(from.vertices.row(v).transpose());
    stats.mean += d / static_cast<double>(from.vertices.rows());
    stats.max = std::max(stats.max, d);
  }
  return stats;
}

Eigen::MatrixXd area_uniform_samples(const offline::io::SurfaceMesh& surface, int samples,
                                     std::uint64_t seed) {
  const Eigen::Index num_triangles = surface.triangles.rows();
  std::vector<double> cumulative(static_cast<std::size_t>(num_triangles));
  double total = 0.0;
  for (Eigen::Index f = 0; f < num_triangles; ++f) {
    const Eigen::Vector3d a = surface.vertices.row(surface.triangles(f, 0)).transpose();
    const Eigen::Vector3d b = surface.vertices.row(surface.triangles(f, 1)).transpose();
    const Eigen::Vector3d c = surface.vertices.row(surface.triangles(f, 2)).transpose();
    total += 0.5 * (b - a).cross(c - a).norm();
    cumulative[static_cast<std::size_t>(f)] = total;
  }
  std::mt19937_64 engine(seed);
  const auto uniform = [&engine] {  // [0, 1), the same on every standard library
    return static_cast<double>(engine() >> 11) * 0x1.0p-53;
  };
  Eigen::MatrixXd points(std::max(samples, 0), 3);
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    const double pick = uniform() * total;
    const auto at = std::upper_bound(cumulative.begin(), cumulative.end(), pick);
    const Eigen::Index f = std::min<Eigen::Index>(at - cumulative.begin(), num_triangles - 1);
    double u = uniform(), v = uniform();
    if (u + v > 1.0) {  // fold the parallelogram's far half onto the triangle
      u = 1.0 - u;
      v = 1.0 - v;
    }
    const Eigen::RowVector3d a = surface.vertices.row(surface.triangles(f, 0));
    const Eigen::RowVector3d b = surface.vertices.row(surface.triangles(f, 1));
    const Eigen::RowVector3d c = surface.vertices.row(surface.triangles(f, 2));
    points.row(i) = a + u * (b - a) + v * (c - a);
  }
  return points;
}

SymmetricSurfaceDistance sampled_surface_distance(const offline::io::SurfaceMesh& a,
                                                  const offline::io::SurfaceMesh& b, int samples,
                                                  std::uint64_t seed) {
  const auto one_way = [samples](const offline::io::SurfaceMesh& from,
                                 const offline::io::SurfaceMesh& to, std::uint64_t draw) {
    const Eigen::MatrixXd points = area_uniform_samples(from, samples, draw);
    const SurfaceDistance query(to);
    SurfaceDistanceStats stats;
    for (Eigen::Index i = 0; i < points.rows(); ++i) {
      const double d = query.distance(points.row(i).transpose());
      stats.mean += d;
      stats.max = std::max(stats.max, d);
    }
    if (points.rows() > 0) stats.mean /= static_cast<double>(points.rows());
    return stats;
  };
  SymmetricSurfaceDistance result;
  result.samples = std::max(samples, 0);
  result.a_to_b = one_way(a, b, seed);
  result.b_to_a = one_way(b, a, seed + 1);
  result.mean = 0.5 * (result.a_to_b.mean + result.b_to_a.mean);
  return result;
}

Eigen::Vector3d SurfaceDistance::triangle_normal(Eigen::Index f) const {
  const Eigen::Vector3d a = surface_.vertices.row(surface_.triangles(f, 0)).transpose();
  const Eigen::Vector3d b = surface_.vertices.row(surface_.triangles(f, 1)).transpose();
  const Eigen::Vector3d c = surface_.vertices.row(surface_.triangles(f, 2)).transpose();
  const Eigen::Vector3d n = (b - a).cross(c - a);
  const double length = n.norm();
  return length > 0.0 ? Eigen::Vector3d(n / length) : Eigen::Vector3d::Zero();
}

}  // namespace sinew::offline
