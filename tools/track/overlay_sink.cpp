#include "tools/track/overlay_sink.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>

#include "tools/io/json_file.hpp"

namespace sinew::tools {

OverlaySink::OverlaySink(std::string target) : target_(std::move(target)) {
  const auto ends_with = [&](const char* suffix) {
    const std::string s(suffix);
    return target_.size() > s.size() &&
           target_.compare(target_.size() - s.size(), s.size(), s) == 0;
  };
  video_file_ = ends_with(".mp4") || ends_with(".avi");
  if (enabled() && !video_file_) std::filesystem::create_directories(target_);
}

void OverlaySink::write(const cv::Mat& picture, int index) {
  if (!enabled()) return;
  if (video_file_) {
    if (!video_.isOpened()) {
      video_.open(target_, cv::VideoWriter::fourcc('m', 'p', '4', 'v'), 30.0, picture.size());
      if (!video_.isOpened()) throw InputError(target_ + ": cannot write a video here");
    }
    video_.write(picture);
    return;
  }
  char name[64];
  std::snprintf(name, sizeof name, "/overlay_%05d.png", index);
  cv::imwrite(target_ + name, picture);
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const std::size_t k =
      std::min(v.size() - 1, static_cast<std::size_t>(std::floor(q * (v.size() - 1) + 0.5)));
  return v[k];
}

}  // namespace sinew::tools
