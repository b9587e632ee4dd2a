#include "offline/meshing/label_image.hpp"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "offline/meshing/surface_closest_point.hpp"

namespace sinew::offline {
namespace {

// In-place separable Gaussian blur along one axis (clamped at the borders: outside = 0).
void blur_axis(std::vector<float>& v, const Eigen::Vector3i& size, int axis, double sigma) {
  const int radius = static_cast<int>(std::ceil(3.0 * sigma));
  std::vector<double> kernel(static_cast<std::size_t>(2 * radius + 1));
  double sum = 0.0;
  for (int r = -radius; r <= radius; ++r) {
    kernel[static_cast<std::size_t>(r + radius)] = std::exp(-0.5 * r * r / (sigma * sigma));
    sum += kernel[static_cast<std::size_t>(r + radius)];
  }
  for (double& k : kernel) k /= sum;
  const Eigen::Index stride[3] = {1, size.x(), static_cast<Eigen::Index>(size.x()) * size.y()};
  const int n = size[axis];
  std::vector<float> line(static_cast<std::size_t>(n));
  const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
  for (int u = 0; u < size[a1]; ++u) {
    for (int w = 0; w < size[a2]; ++w) {
      const Eigen::Index base = u * stride[a1] + w * stride[a2];
      for (int i = 0; i < n; ++i)
        line[static_cast<std::size_t>(i)] = v[static_cast<std::size_t>(base + i * stride[axis])];
      for (int i = 0; i < n; ++i) {
        double acc = 0.0;
        for (int r = -radius; r <= radius; ++r) {
          const int j = i + r;
          if (j >= 0 && j < n)
            acc += kernel[static_cast<std::size_t>(r + radius)] * line[static_cast<std::size_t>(j)];
        }
        v[static_cast<std::size_t>(base + i * stride[axis])] = static_cast<float>(acc);
      }
    }
  }
}

}  // namespace

std::vector<float> label_indicator(const io::VolumeImage& image, const LabelMeshOptions& options) {
  std::vector<float> indicator(image.values.size());
  bool any = false;
  for (std::size_t i = 0; i < image.values.size(); ++i) {
    const float v = image.values[i];
    const bool inside = options.label < 0 ? v > 0.5f : std::lround(v) == options.label;
    indicator[i] = inside ? 1.0f : 0.0f;
    any |= inside;
  }
  if (!any) return {};
  if (options.smoothing_voxels > 0.0) {
    for (int axis = 0; axis < 3; ++axis)
      blur_axis(indicator, image.size, axis, options.smoothing_voxels);
  }
  return indicator;
}

TetMesherResult mesh_label_region(const io::VolumeImage& image, const LabelMeshOptions& options) {
  const std::vector<float> indicator = label_indicator(image, options);
  TetMesherResult result;
  if (indicator.empty()) {
    result.summary.status = TetMesherStatus::kEmptyMesh;
    result.summary.message = options.label < 0
                                 ? "the mask has no voxel > 0.5"
                                 : "label " + std::to_string(options.label) + " occurs in no voxel";
    return result;
  }
  // The mesher works on the grid (i·1, j·1, k·1) scaled by the voxel lengths; world = A·ijk.
  const Eigen::Vector3d spacing = image.spacing();
  result = make_tet_mesh_from_image(indicator, image.size, spacing, 0.5, options.mesher);
  if (!result.summary.ok()) return result;
  auto& V = result.mesh.vertices;
  bool reflect = image.index_to_world.topLeftCorner<3, 3>().determinant() < 0.0;
  for (Eigen::Index v = 0; v < V.rows(); ++v) {
    const Eigen::Vector3d ijk = V.row(v).transpose().cwiseQuotient(spacing);
    Eigen::Vector3d world = image.world(ijk);
    if (options.mirror_plane_x) world.x() = 2.0 * *options.mirror_plane_x - world.x();
    V.row(v) = world.transpose();
  }
  if (options.mirror_plane_x) reflect = !reflect;
  if (reflect) result.mesh.tets.col(2).swap(result.mesh.tets.col(3));  // keep right-handed
  return result;
}

std::vector<Eigen::Vector3d> farthest_point_selection(const std::vector<Eigen::Vector3d>& points,
                                                      int count) {
  std::vector<Eigen::Vector3d> chosen;
  if (points.empty() || count <= 0) return chosen;
  std::vector<double> distance(points.size(), std::numeric_limits<double>::infinity());
  std::size_t next = 0;
  for (int k = 0; k < count && k < static_cast<int>(points.size()); ++k) {
    chosen.push_back(points[next]);
    std::size_t farthest = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
      distance[i] = std::min(distance[i], (points[i] - chosen.back()).norm());
      if (distance[i] > distance[farthest]) farthest = i;
    }
    next = farthest;
  }
  return chosen;
}

std::vector<Eigen::Vector3d> sample_surface_points(const Eigen::Ref<const Eigen::MatrixXd>& V,
                                                   const Eigen::Ref<const Eigen::MatrixXi>& F,
                                                   int count, unsigned seed) {
  auto corner = [&](Eigen::Index f, int k) -> Eigen::Vector3d {
    return V.row(F(f, k)).transpose();
  };
  std::vector<double> cumulative;
  double total = 0.0;
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    total += 0.5 * (corner(f, 1) - corner(f, 0)).cross(corner(f, 2) - corner(f, 0)).norm();
    cumulative.push_back(total);
  }
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Eigen::Vector3d> points;
  if (F.rows() == 0) return points;
  points.reserve(static_cast<std::size_t>(std::max(count, 0)));
  for (int k = 0; k < count; ++k) {
    const auto f = static_cast<Eigen::Index>(
        std::lower_bound(cumulative.begin(), cumulative.end(), u(rng) * total) -
        cumulative.begin());
    double r1 = u(rng), r2 = u(rng);
    if (r1 + r2 > 1.0) {  // reflect into the triangle
      r1 = 1.0 - r1;
      r2 = 1.0 - r2;
    }
    points.push_back(corner(f, 0) + r1 * (corner(f, 1) - corner(f, 0)) +
                     r2 * (corner(f, 2) - corner(f, 0)));
  }
  return points;
}

std::optional<std::vector<Eigen::Vector3d>> sample_label_boundary(const io::VolumeImage& image,
                                                                  const LabelMeshOptions& options,
                                                                  int count, unsigned seed,
                                                                  std::string* error) {
  auto fail = [&](const std::string& message) -> std::optional<std::vector<Eigen::Vector3d>> {
    if (error != nullptr) *error = message;
    return std::nullopt;
  };
  if (count < 1) return fail("marker count " + std::to_string(count) + " must be >= 1");
  const TetMesherResult meshed = mesh_label_region(image, options);
  if (!meshed.summary.ok()) return fail("meshing the label region: " + meshed.summary.message);
  const auto boundary = BoundarySurface::extract(meshed.mesh.vertices.rows(), meshed.mesh.tets);
  if (!boundary) return fail("the label region's mesh has no valid boundary");
  // Area-weighted candidates (50 per requested point, at least 5,000), then farthest points.
  const std::vector<Eigen::Vector3d> points = sample_surface_points(
      meshed.mesh.vertices, boundary->triangles(), std::max(5000, 50 * count), seed);
  return farthest_point_selection(points, count);
}

}  // namespace sinew::offline
