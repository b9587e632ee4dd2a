#pragma once
/// Whether a pixel lies in cv::dilate(mask, MORPH_ELLIPSE of (2 reach + 1)²), asked only where it
/// matters: whisker detection asks it at the dark pixels off the face, and dilating the whole frame
/// was 10 % of detection. Each row of OpenCV's ellipse is a centred run of half-width w_j, so a
/// pixel is covered when, in the row j − reach away, the nearest set pixel of the mask lies within
/// w_j along the row. Should a kernel row not be a centred run, it falls back on cv::dilate.
/// Set-up work (allocates), outside the fixed-allocation core.

#include <opencv2/core.hpp>
#include <vector>

namespace sinew::rt::detail {

class EllipseDilation {
 public:
  /// mask: CV_8U, non-zero = set; reach ≥ 0 (reach 255 px at most: distances are kept in bytes).
  EllipseDilation(const cv::Mat& mask, int reach);
  /// As cv::dilate(mask, ellipse)(y, x) != 0; (x, y) inside the mask.
  bool covers(int x, int y) const;

 private:
  int reach_;
  std::vector<int> half_;
  cv::Mat along_, dilated_;
};

}  // namespace sinew::rt::detail
