#pragma once
/// Renders sinew-synth's frames: a bright, mildly shaded background with fixed clutter segments,
/// the beam as a dark anti-aliased band around its true (fine) centreline, an optional textured
/// occluder over the middle fifth of the beam, the camera's homography and sensor noise.
///
/// The scene is drawn in reference-frame pixels (pixel centres at integers) and then warped by the
/// frame's homography, so truth positions map to frame pixels by H. With camera motion the scene is
/// drawn on a canvas padded on every side, so that what the moving camera brings into view is more
/// of the same background and clutter rather than a reflection. Seeded: the same options give the
/// same images, byte for byte.

#include <opencv2/core.hpp>

#include "tools/synth/scenario.hpp"

namespace sinew::tools::synth {

/// Grey levels of the scene (before noise).
inline constexpr double kBackgroundGrey = 200.0;
inline constexpr double kBeamGrey = 60.0;
inline constexpr double kOccluderGrey = 128.0;

class Renderer {
 public:
  /// Builds the static background (shading and clutter) and the occluder's texture. The options and
  /// the simulation must outlive the renderer.
  Renderer(const SynthOptions& options, const Simulation& simulation);

  /// Frame `frame` as an 8-bit grey image (height x width). Frames must be rendered in order
  /// 0, 1, 2, ... for the noise to be reproducible.
  cv::Mat render(int frame);

 private:
  /// The noise-free scene of frame `frame` on the canvas (reference pixels + pad_), CV_32F.
  cv::Mat render_canvas(int frame) const;
  // Both take canvas coordinates.
  void draw_beam(cv::Mat& canvas, const Eigen::Matrix2Xd& centreline) const;
  void draw_occluder(cv::Mat& canvas, const Eigen::Matrix2Xd& centreline) const;

  const SynthOptions& options_;
  const Simulation& simulation_;
  int pad_ = 0;               // canvas border, pixels (0 without camera motion)
  cv::Mat background_;        // CV_32F canvas: shading and clutter
  cv::Mat occluder_texture_;  // CV_32F canvas: mid-grey noise texture, fixed in the scene
  cv::RNG noise_rng_;
};

}  // namespace sinew::tools::synth
