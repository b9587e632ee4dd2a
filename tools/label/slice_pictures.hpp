#pragma once
/// Axial cross-sections of a registered surface over a scan (seed 003 Fig. 18), for `sinew-label
/// slices` and for `sinew-register` when a case names its scan image: K slices evenly over the
/// surface's extent, the image in a grey window, the surface's cross-section in red and, with a
/// mask, the mask's outline in green; per slice the mean in-plane distance from the red curve to
/// the green outline. Radiological orientation (the patient's left on the right, anterior up;
/// NIfTI world is RAS+).
#include <optional>
#include <string>
#include <vector>

#include "offline/io/surface_mesh_io.hpp"
#include "offline/io/volume_image_io.hpp"

namespace sinew::tools {

struct SlicePictureOptions {
  int count = 6;             ///< slices, ≥ 1
  double window_low = -160;  ///< grey window of the background (image values)
  double window_high = 240;  ///< > window_low
  int zoom = 4;              ///< pixels per voxel, ≥ 1
  int label = -1;            ///< mask label drawn; < 0: every voxel > 0.5
};

struct SlicePicture {
  std::string file;  ///< the PNG written
  int k = 0;         ///< slice index
  /// Mean distance (image units, in-plane) from the cross-section to the mask's outline; set
  /// when a mask was given and the surface cuts the slice.
  std::optional<double> mean_distance;
};

/// Writes out_dir/slice_kNNN.png for each slice (creating out_dir). mask, when given, must have
/// image's grid (checked by the caller). surface in the image's world coordinates.
std::vector<SlicePicture> write_slice_pictures(const offline::io::VolumeImage& image,
                                               const offline::io::VolumeImage* mask,
                                               const offline::io::SurfaceMesh& surface,
                                               const std::string& out_dir,
                                               const SlicePictureOptions& options = {});

}  // namespace sinew::tools
