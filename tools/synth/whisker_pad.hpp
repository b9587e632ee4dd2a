#pragma once
/// sinew-synth --scenario whisker-pad: a rendered head-fixed (or moving) rodent's whisker pad with
/// known truth, for the whisker tracker's end-to-end tests.
///
/// Scene (reference 640 x 480; scaled to --width/--height): a dark face whose edge is an ellipse
/// arc on the left; N whiskers leaving it, each a curved tapered cantilever (length 120–220 px,
/// width 3 → 1 px, darkening from its base contrast to 40 % of it at the tip), base contrasts
/// spread evenly over [contrast_min, contrast_max] grey levels; a graded backlight; whisking (base
/// angles oscillating ±10° at whisk_hz, camera at fps); one crossing pair (whiskers 2 and 3 curve
/// towards each other); a static dark pole that the last whisker presses against on part of each
/// whisk cycle (the contact force from the project's own StaticBeamSolver, found so that the
/// whisker's contact point rests on the pole's surface; optionally sliding along that whisker, so
/// that the contact point moves along it); a dark lick-port-like object; optional
/// face motion (translation and rotation of the whole head, follicles and whiskers with it).
///
/// truth.jsonl: per frame {"frame", "face": {"translation": [x, y], "rotation_deg"}, "whiskers":
/// [{"id", "follicle": [x, y], "base_angle_deg", "centreline": [[x, y] ...] (the simulation's
/// nodes, follicle first, ~3 px apart), "contrast", "contact": null | {"point": [x, y],
/// "arc_length_px", "force": [fx, fy]}}]}; pixel centres at integers.

#include <cstdint>
#include <string>

namespace sinew::tools::synth {

struct WhiskerPadOptions {
  int frames = 200;
  int width = 640;
  int height = 480;
  int whiskers = 8;
  double noise = 4.0;          ///< σ of the Gaussian noise, grey levels
  double contrast_min = 5.0;   ///< base contrast of the faintest whisker, grey levels
  double contrast_max = 20.0;  ///< of the darkest
  double whisk_hz = 10.0;      ///< base-angle oscillation
  double fps = 500.0;          ///< camera frame rate
  bool face_motion = false;    ///< the head translates and rotates
  bool pole = true;            ///< a pole the last whisker presses against
  /// The pole slides along the pressed whisker from 60 % of its length towards its follicle by up
  /// to this fraction of the length and back (one cosine period over the sequence), so that the
  /// contact point moves along the whisker and the load grows; in [0, 0.3]. 0: a static pole.
  double pole_travel = 0.0;
  bool lick_port = true;  ///< a dark static object away from the whiskers
  std::uint64_t seed = 1;
};

/// Simulates, renders and writes DIR/frames/f_NNNN.png and DIR/truth.jsonl. Throws
/// std::runtime_error (one line) when the contact solve fails.
void write_whisker_pad(const WhiskerPadOptions& options, const std::string& out_dir);

}  // namespace sinew::tools::synth
