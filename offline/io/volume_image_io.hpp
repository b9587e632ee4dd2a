#pragma once
/// Volume images from scans and segmentations (issue: label images as a source of ICP markers and
/// templates): NIfTI-1 (`.nii`, `.nii.gz`, the format of TotalSegmentator, 3D Slicer, ITK-SNAP) and
/// INRIA (`.inr`, `.inr.gz`, CGAL's and the liver demo's format). gzip-compressed files are read
/// through zlib.
///
/// Physical coordinates: index_to_world maps voxel indices (i, j, k) to millimetres in the file's
/// frame. NIfTI: the sform when sform_code > 0, else the qform quaternion (qform_code > 0), else
/// the pixel sizes alone (NIfTI's "method 1"); the world is RAS+ by the NIfTI convention. INRIA:
/// the voxel sizes VX, VY, VZ and the origin TX, TY, TZ when given. Values are converted to float
/// (labels up to 2²⁴ are exact), with NIfTI's scl_slope/scl_inter applied when set.
///
/// Errors are one line naming the file and what is wrong (unsupported datatype, truncated data,
/// 4D images, ...).

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

namespace sinew::offline::io {

struct VolumeImage {
  Eigen::Vector3i size = Eigen::Vector3i::Zero();  ///< voxels along i, j, k
  /// world = index_to_world · [i, j, k, 1]ᵀ (top 3 rows used), millimetres.
  Eigen::Matrix4d index_to_world = Eigen::Matrix4d::Identity();
  std::vector<float> values;  ///< i fastest, then j, then k

  Eigen::Index index(int i, int j, int k) const {
    return (static_cast<Eigen::Index>(k) * size.y() + j) * size.x() + i;
  }
  float at(int i, int j, int k) const { return values[static_cast<std::size_t>(index(i, j, k))]; }
  Eigen::Vector3d world(const Eigen::Vector3d& ijk) const {
    return index_to_world.topLeftCorner<3, 3>() * ijk + index_to_world.topRightCorner<3, 1>();
  }
  /// Lengths of the three voxel axes in world units.
  Eigen::Vector3d spacing() const { return index_to_world.topLeftCorner<3, 3>().colwise().norm(); }
};

struct VolumeImageReadResult {
  std::optional<VolumeImage> image;
  std::string error;  ///< one line on failure
};

/// Reads a NIfTI-1 or INRIA image, chosen by the file name (.nii, .nii.gz, .inr, .inr.gz).
VolumeImageReadResult read_volume_image(const std::string& path);

/// Writes a NIfTI-1 single file (.nii, or gzip-compressed .nii.gz), float32 voxels, the transform
/// as sform (and qform_code 0). Written to a temporary name and renamed (atomic). False with error.
bool write_nifti(const std::string& path, const VolumeImage& image, std::string* error = nullptr);

}  // namespace sinew::offline::io
