#include "offline/registration/template_surface.hpp"

#include <algorithm>
#include <cmath>

namespace sinew::offline {
namespace {

// Mean edge length of the tets at rest.
double mean_tet_edge(const common::TetIndices& tets, const Eigen::VectorXd& rest) {
  double sum = 0.0;
  for (Eigen::Index t = 0; t < tets.rows(); ++t) {
    for (int a = 0; a < 4; ++a) {
      for (int b = a + 1; b < 4; ++b) {
        sum += (rest.segment<3>(3 * tets(t, a)) - rest.segment<3>(3 * tets(t, b))).norm();
      }
    }
  }
  return sum / (6.0 * static_cast<double>(std::max<Eigen::Index>(tets.rows(), 1)));
}

}  // namespace

TemplateSurfaceClosestPoint::TemplateSurfaceClosestPoint(
    const common::TetIndices& tets, const Eigen::VectorXd& rest,
    const offline::TetPointLocator& locator, const Eigen::MatrixXi& triangles,
    const std::vector<offline::EmbeddedPoint>& vertex_points)
    : tets_(tets), locator_(&locator) {
  // Triangles longer than the tets are split into n x n (n = ⌈longest edge / mean tet edge⌉), the
  // new points embedded by the locator: a flat template triangle much larger than the tets is
  // not the image of the deformation between its corners.
  const double max_edge = mean_tet_edge(tets, rest);
  std::vector<Eigen::Vector3d> positions;
  auto add_point = [&](const Eigen::Vector3d& X, const offline::EmbeddedPoint* known) {
    if (known != nullptr) {
      points_.push_back(*known);
    } else {
      const offline::Embedding e = locator.locate(X);
      points_.push_back(e.ok() ? e.point : offline::EmbeddedPoint{});
    }
    positions.push_back(X);
    return static_cast<int>(positions.size()) - 1;
  };
  std::vector<int> corner_index(vertex_points.size(), -1);
  std::vector<Eigen::Vector3i> refined;
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    Eigen::Vector3d X[3];
    for (int k = 0; k < 3; ++k) {
      X[k] = offline::embedded_position(
          tets, vertex_points[static_cast<std::size_t>(triangles(f, k))], rest);
    }
    const double longest =
        std::max({(X[1] - X[0]).norm(), (X[2] - X[1]).norm(), (X[0] - X[2]).norm()});
    const int n = std::max(1, static_cast<int>(std::ceil(longest / max_edge)));
    // Grid point (i, j) = X0 + i/n (X1 − X0) + j/n (X2 − X0), i + j ≤ n; corners reuse the
    // vertices' own embeddings (shared between triangles).
    std::vector<int> grid(static_cast<std::size_t>((n + 1) * (n + 1)), -1);
    auto at = [&](int i, int j) -> int& { return grid[static_cast<std::size_t>(i * (n + 1) + j)]; };
    for (int i = 0; i <= n; ++i) {
      for (int j = 0; i + j <= n; ++j) {
        int corner = -1;
        if (i == 0 && j == 0) corner = 0;
        if (i == n) corner = 1;
        if (j == n) corner = 2;
        if (corner >= 0) {
          const auto v = static_cast<std::size_t>(triangles(f, corner));
          if (corner_index[v] < 0) corner_index[v] = add_point(X[corner], &vertex_points[v]);
          at(i, j) = corner_index[v];
        } else {
          at(i, j) = add_point(X[0] + (static_cast<double>(i) / n) * (X[1] - X[0]) +
                                   (static_cast<double>(j) / n) * (X[2] - X[0]),
                               nullptr);
        }
      }
    }
    for (int i = 0; i < n; ++i) {
      for (int j = 0; i + j < n; ++j) {
        refined.emplace_back(at(i, j), at(i + 1, j), at(i, j + 1));
        if (i + j + 1 < n) refined.emplace_back(at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
      }
    }
  }
  rest_positions_.resize(static_cast<Eigen::Index>(positions.size()), 3);
  for (std::size_t i = 0; i < positions.size(); ++i)
    rest_positions_.row(static_cast<Eigen::Index>(i)) = positions[i].transpose();
  triangles_.resize(static_cast<Eigen::Index>(refined.size()), 3);
  for (std::size_t f = 0; f < refined.size(); ++f)
    triangles_.row(static_cast<Eigen::Index>(f)) = refined[f].transpose();
  vertex_triangles_.resize(positions.size());
  for (Eigen::Index f = 0; f < triangles_.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      vertex_triangles_[static_cast<std::size_t>(triangles_(f, k))].push_back(f);
    }
  }
}

void TemplateSurfaceClosestPoint::update(const Eigen::Ref<const Eigen::VectorXd>& x) {
  x_ = x;
  offline::io::SurfaceMesh deformed;
  deformed.triangles = triangles_;
  deformed.vertices.resize(rest_positions_.rows(), 3);
  for (std::size_t i = 0; i < points_.size(); ++i) {
    deformed.vertices.row(static_cast<Eigen::Index>(i)) =
        offline::embedded_position(tets_, points_[i], x).transpose();
  }
  deformed_.emplace(deformed);
}

offline::EmbeddedPoint TemplateSurfaceClosestPoint::closest(const Eigen::Vector3d& query) const {
  const SurfaceDistance::Closest c = deformed_->closest(query);
  Eigen::Vector3d X = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k) {
    X += c.barycentric[k] * rest_positions_.row(triangles_(c.triangle, k)).transpose();
  }
  const offline::Embedding e = locator_->locate(X);
  if (e.ok()) return e.point;
  // Not embeddable (not expected: the corners were): the corner with the largest weight.
  Eigen::Index corner = 0;
  c.barycentric.maxCoeff(&corner);
  return points_[static_cast<std::size_t>(triangles_(c.triangle, corner))];
}

Eigen::Vector3d TemplateSurfaceClosestPoint::normal(const Eigen::Vector3d& query) const {
  // A function of the closest point alone, not of which of the triangles holding it (an edge, a
  // corner) the search returned: that choice follows the last bits of x and so the machine's
  // BLAS kernels (see offline::BoundaryClosestPoint::normal, the same rule on the tet boundary).
  const SurfaceDistance::Closest c = deformed_->closest(query);
  const Eigen::Vector3d own = deformed_->triangle_normal(c.triangle);
  const auto corner = [&](int k) {
    return offline::embedded_position(
        tets_, points_[static_cast<std::size_t>(triangles_(c.triangle, k))], x_);
  };
  const Eigen::Vector3d a = corner(0), b = corner(1), d = corner(2);
  const double size = std::max({(b - a).norm(), (d - b).norm(), (a - d).norm()});
  if (c.distance > 1e-6 * size) return Eigen::Vector3d((query - c.point) / c.distance);
  std::vector<int> support;  // the triangle's vertices the closest point depends on
  for (int k = 0; k < 3; ++k) {
    if (c.barycentric[k] > 0.0) support.push_back(triangles_(c.triangle, k));
  }
  if (support.size() == 3 || support.empty()) return own;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const Eigen::Index f : vertex_triangles_[static_cast<std::size_t>(support.front())]) {
    bool holds = true;
    for (const int v : support) {
      holds = holds && (triangles_(f, 0) == v || triangles_(f, 1) == v || triangles_(f, 2) == v);
    }
    if (holds) sum += deformed_->triangle_normal(f);
  }
  const double length = sum.norm();
  return length > 0.0 ? Eigen::Vector3d(sum / length) : own;
}

}  // namespace sinew::offline
