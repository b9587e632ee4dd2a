#pragma once
/// Frames for sinew-track from a video file, a single image, a folder of images or a printf pattern
/// (frames/f_%04d.png), always as 8-bit grey, with --first/--stride/--count applied.

#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>
#include <string>
#include <vector>

namespace sinew::tools {

class FrameSource {
 public:
  /// Opens `input`; throws InputError with a one-line reason when it cannot be read.
  FrameSource(const std::string& input, int first, int stride, int count);

  /// Next processed frame as grey (CV_8UC1) and its index in the input; false at the end.
  bool next(cv::Mat& grey, int& index);
  const std::string& description() const { return description_; }

 private:
  bool read_raw(cv::Mat& frame);  // the next frame of the input, any type

  std::string input_;
  std::string description_;
  std::vector<std::string> files_;  // folder or single image
  cv::VideoCapture capture_;
  bool use_capture_ = false;
  int first_, stride_, count_;
  int raw_index_ = -1;  // index of the last raw frame read
  int delivered_ = 0;
  cv::Mat buffer_;
};

}  // namespace sinew::tools
