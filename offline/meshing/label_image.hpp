#pragma once
/// Segmentation label images as registration inputs (seed 003 §4: templates and markers come from
/// segmented CT/MRI): the region of one label is smoothed (Gaussian, in voxels) into a [0, 1]
/// indicator whose 0.5 iso-surface is a sub-voxel boundary, and
///  - tet-meshed (CGAL gray-image domain, offline/meshing/tet_mesher.hpp) in world coordinates,
///    optionally mirrored across a plane x = c (a left organ from a right one);
///  - sampled: a requested number of well-spread points on that boundary (area-weighted candidates,
///    then farthest-point selection), as ICP markers in the image's physical coordinates.
/// Coordinates are the image's world frame (offline/io/volume_image_io.hpp: NIfTI RAS+ mm).

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "offline/io/volume_image_io.hpp"
#include "offline/meshing/tet_mesher.hpp"

namespace sinew::offline {

struct LabelMeshOptions {
  /// The voxels with this value form the region; < 0: every voxel > 0.5 (a binary mask).
  int label = -1;
  /// Gaussian smoothing of the 0/1 indicator, standard deviation in voxels; ≥ 0 (0: none, the
  /// boundary then follows the voxel faces' trilinear interpolation).
  double smoothing_voxels = 0.8;
  /// Mirror the result across the plane x = mirror_plane_x (world units) when set.
  std::optional<double> mirror_plane_x;
  TetMesherOptions mesher{};
};

/// The smoothed indicator of the region (values in [0, 1], same grid as image). Empty when the
/// label occurs nowhere.
std::vector<float> label_indicator(const io::VolumeImage& image, const LabelMeshOptions& options);

/// Tet mesh of the region in world coordinates (right-handed tets), or a failure in summary.
TetMesherResult mesh_label_region(const io::VolumeImage& image, const LabelMeshOptions& options);

/// `count` well-spread points on the region's boundary surface (world coordinates), seeded.
/// std::nullopt (with error) when the region cannot be meshed or count < 1.
std::optional<std::vector<Eigen::Vector3d>> sample_label_boundary(const io::VolumeImage& image,
                                                                  const LabelMeshOptions& options,
                                                                  int count, unsigned seed = 1,
                                                                  std::string* error = nullptr);

/// `count` points on a triangle surface, uniformly distributed by area (seeded; std::mt19937).
std::vector<Eigen::Vector3d> sample_surface_points(
    const Eigen::Ref<const Eigen::MatrixXd>& vertices,
    const Eigen::Ref<const Eigen::MatrixXi>& triangles, int count, unsigned seed);

/// Farthest-point selection of `count` of the points (from the first): well spread.
std::vector<Eigen::Vector3d> farthest_point_selection(const std::vector<Eigen::Vector3d>& points,
                                                      int count);

}  // namespace sinew::offline
