#pragma once
/// Moving cameras (seed 000 §5.2, the pole vault): maps every frame into the coordinates of a
/// reference frame by a homography, so the tracker sees a static camera and its fixed dofs stay
/// where the object is held. The homography is estimated by direct (ECC) alignment of the whole
/// frame against the reference on a 2x-downsampled image, warm-started from the previous frame,
/// with the tracked object masked out (it moves relative to the background). Also the seed's helper
/// that finds a fixed ground point as the intersection of two straight poses.
///
/// This runs outside the fixed-allocation core (OpenCV allocates); its cost is reported apart.

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <optional>
#include <string>

namespace sinew::rt {

struct StabiliserOptions {
  /// ECC iterations per frame (bound), ≥ 1.
  int max_iterations = 30;
  /// ECC stops when the correlation improves by less than this, > 0.
  double epsilon = 1e-4;
  /// Width of the band masked around the tracked object, pixels (full resolution), ≥ 0.
  double mask_half_width_px = 20.0;
  /// Below this correlation coefficient the alignment is reported failed, (0, 1).
  double min_correlation = 0.5;

  std::optional<std::string> validate() const;
};

struct StabiliserSummary {
  bool ok = false;
  double correlation = 0.0;  ///< ECC correlation coefficient at the end
  double seconds = 0.0;
  Eigen::Matrix3d homography = Eigen::Matrix3d::Identity();  ///< reference pixels → frame pixels
};

class Stabiliser {
 public:
  /// reference: the 8-bit grey frame whose coordinates everything is mapped into.
  Stabiliser(const cv::Mat& reference, StabiliserOptions options = {});

  /// Estimates the homography H (reference → frame) warm-started from the previous one, with the
  /// polyline `object` (reference coordinates; may be empty) masked out, and writes the frame
  /// resampled into the reference coordinates to `stabilised`.
  StabiliserSummary stabilise(const cv::Mat& frame, const Eigen::Matrix2Xd& object,
                              cv::Mat& stabilised);

 private:
  StabiliserOptions options_;
  cv::Mat reference_small_;  // CV_32F, half resolution
  cv::Mat warp_small_;       // 3x3 CV_32F, half-resolution homography, warm start
};

/// The seed's ground point: intersection of the straight lines through two straight poses of a
/// pole (each a polyline, least-squares line fit). Empty when the lines are (nearly) parallel.
std::optional<Eigen::Vector2d> intersect_straight_poses(const Eigen::Matrix2Xd& pose_a,
                                                        const Eigen::Matrix2Xd& pose_b);

}  // namespace sinew::rt
