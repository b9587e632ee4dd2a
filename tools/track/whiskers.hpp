#pragma once
/// sinew-track --whiskers: finds every whisker on the first frame (rt::detect_whiskers) and tracks
/// them all (rt::WhiskerTracker). One JSON line per frame:
/// {"frame", "latency_us", "whiskers": [{"id", "status", "nodes": [[x, y, θ]...], "follicle",
/// "tip", "length_px", "inlier_fraction", read-out and contact ...}], "redetect": {...}}; the
/// first line before the frames is the detection record {"detection": {...}}.

#include <string>

#include "rt/whisker/readout.hpp"
#include "rt/whisker/whisker_tracker.hpp"

namespace sinew::tools {

struct WhiskerTrackArgs {
  std::string input, out, overlay, face = "auto";
  int first = 0, stride = 1, count = -1;
  bool quiet = false;
  double min_length_px = 40.0;
  bool repair_traces = false;      ///< rt::WhiskerDetectionOptions::repair_traces
  double associate_home_px = 0.0;  ///< rt::WhiskerTrackerOptions::associate_home_px
  double held_ridge_px = rt::WhiskerTrackerOptions{}.held_ridge_px;  ///< ... ::held_ridge_px
  double associate_contrast_ratio =
      rt::WhiskerTrackerOptions{}.associate_contrast_ratio;  ///< ... ::associate_contrast_ratio
  /// rt::TrackerOptions::start_clearance_px of every whisker (the follicle angle's bias)
  double start_clearance_px = 0.0;
  /// rt::TrackerOptions::start_mean_surround_px of every whisker (the follicle's sideways bias)
  double start_mean_surround_px = 0.0;
  /// rt::TrackerOptions::ridge_position_from_profile of every whisker
  bool profile_position = false;
  /// Detection after tracking, for rt::WhiskerTracker::associate: "every" frame (a 25–100 fps
  /// camera, whose whiskers move further between frames than the search reaches), only on frames
  /// with a "lost" whisker (a high-speed camera), or "never".
  std::string redetect = "every";
  /// The frame whose fits are the whiskers at rest (rt::WhiskerSessionOptions::rest_frame).
  int rest_frame = 0;
  int rest_frames = 1;
  bool fit_follicle_position = false;  ///< rt::LoadFitOptions::fit_base_translation
  /// The read-out: physics (scale, material, taper), head axis, curvature window; and a CSV file
  /// with one row per whisker per frame (empty: none).
  rt::WhiskerReadoutOptions readout;
  std::string csv;
  /// Folder for per-whisker time-series PNGs (empty: none).
  std::string plots;
  /// HDF5 file with the table and the full centrelines (tools/track/whisker_hdf5.hpp; empty: none).
  std::string hdf5;
  /// PNG of the first frame's detection, magnified: every whisker found (id colour, follicle dot)
  /// and every trace that was not, coloured by the reason (empty: none).
  std::string detection_picture;
};

/// Runs it; throws InputError on bad input. Returns the exit status.
int run_whiskers(const WhiskerTrackArgs& args);

}  // namespace sinew::tools
