#include "tools/track/frame_source.hpp"

#include <algorithm>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "tools/io/json_file.hpp"

namespace sinew::tools {

namespace {
bool is_image_file(const std::filesystem::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  return ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".tif" || ext == ".tiff" ||
         ext == ".bmp" || ext == ".pgm" || ext == ".ppm";
}
}  // namespace

FrameSource::FrameSource(const std::string& input, int first, int stride, int count)
    : input_(input), first_(first), stride_(stride), count_(count) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (input.find('%') != std::string::npos) {
    capture_.open(input, cv::CAP_IMAGES);
    if (!capture_.isOpened()) throw InputError(input + ": no images match this pattern");
    use_capture_ = true;
    description_ = "image sequence " + input;
  } else if (fs::is_directory(input, ec)) {
    for (const auto& entry : fs::directory_iterator(input)) {
      if (entry.is_regular_file() && is_image_file(entry.path()))
        files_.push_back(entry.path().string());
    }
    std::sort(files_.begin(), files_.end());
    if (files_.empty())
      throw InputError(input + ": folder holds no images (png, jpg, tif, bmp, pgm)");
    description_ = "folder " + input + " (" + std::to_string(files_.size()) + " images)";
  } else if (!fs::exists(input, ec)) {
    throw InputError(input + ": no such file or folder");
  } else if (is_image_file(input)) {
    files_.push_back(input);
    description_ = "image " + input;
  } else {
    capture_.open(input, cv::CAP_FFMPEG);
    if (!capture_.isOpened()) capture_.open(input);
    if (!capture_.isOpened()) throw InputError(input + ": cannot open as a video or an image");
    use_capture_ = true;
    description_ = "video " + input;
  }
}

bool FrameSource::read_raw(cv::Mat& frame) {
  ++raw_index_;
  if (use_capture_) return capture_.read(frame) && !frame.empty();
  if (raw_index_ >= static_cast<int>(files_.size())) return false;
  frame = cv::imread(files_[raw_index_], cv::IMREAD_UNCHANGED);
  if (frame.empty()) throw InputError(files_[raw_index_] + ": cannot read this image");
  return true;
}

bool FrameSource::next(cv::Mat& grey, int& index) {
  if (count_ >= 0 && delivered_ >= count_) return false;
  const int wanted = first_ + delivered_ * stride_;
  while (raw_index_ < wanted) {
    if (!read_raw(buffer_)) return false;
  }
  index = raw_index_;
  if (buffer_.channels() == 3) {
    cv::cvtColor(buffer_, grey, cv::COLOR_BGR2GRAY);
  } else if (buffer_.channels() == 4) {
    cv::cvtColor(buffer_, grey, cv::COLOR_BGRA2GRAY);
  } else {
    grey = buffer_;
  }
  if (grey.depth() == CV_16U) grey.convertTo(grey, CV_8U, 1.0 / 256.0);
  if (grey.type() != CV_8UC1)
    throw InputError(input_ + ": frame " + std::to_string(index) + " is not an 8- or 16-bit image");
  ++delivered_;
  return true;
}

}  // namespace sinew::tools
