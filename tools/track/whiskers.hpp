#pragma once
/// sinew-track --whiskers: finds every whisker on the first frame (rt::detect_whiskers) and tracks
/// them all (rt::WhiskerTracker). One JSON line per frame:
/// {"frame", "latency_us", "whiskers": [{"id", "status", "nodes": [[x, y, θ]...], "follicle",
/// "tip", "length_px", "inlier_fraction"}]}; the first line before the frames is the detection
/// record {"detection": {...}}.

#include <string>

namespace sinew::tools {

struct WhiskerTrackArgs {
  std::string input, out, overlay, face = "auto";
  int first = 0, stride = 1, count = -1;
  bool quiet = false;
  double min_length_px = 40.0;
};

/// Runs it; throws InputError on bad input. Returns the exit status.
int run_whiskers(const WhiskerTrackArgs& args);

}  // namespace sinew::tools
