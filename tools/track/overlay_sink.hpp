#pragma once
/// Where sinew-track's overlay pictures go (a folder of PNGs or one .mp4/.avi video), and the
/// percentiles it prints. Shared by the single-object and the whisker paths.

#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>
#include <string>
#include <vector>

namespace sinew::tools {

class OverlaySink {
 public:
  /// `target`: empty (no overlay), a file ending in .mp4 or .avi, or a folder (created).
  explicit OverlaySink(std::string target);
  bool enabled() const { return !target_.empty(); }
  /// Writes frame `index`'s picture. Throws InputError when the video cannot be written.
  void write(const cv::Mat& picture, int index);

 private:
  std::string target_;
  bool video_file_ = false;
  cv::VideoWriter video_;
};

/// The q-quantile (nearest rank) of v; 0 for an empty v.
double percentile(std::vector<double> v, double q);

}  // namespace sinew::tools
