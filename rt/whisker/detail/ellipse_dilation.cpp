#include "rt/whisker/detail/ellipse_dilation.hpp"

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <opencv2/imgproc.hpp>

namespace sinew::rt::detail {

EllipseDilation::EllipseDilation(const cv::Mat& mask, int reach) : reach_(reach) {
  const cv::Mat kernel =
      cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * reach + 1, 2 * reach + 1));
  half_.assign(static_cast<std::size_t>(kernel.rows), -1);
  for (int j = 0; j < kernel.rows; ++j) {
    const std::uint8_t* k = kernel.ptr<std::uint8_t>(j);
    int w = k[reach] ? 0 : -1;
    while (w >= 0 && w < reach && k[reach + w + 1] && k[reach - w - 1]) ++w;
    for (int x = 0; x < kernel.cols; ++x) {
      if ((k[x] != 0) != (w >= 0 && std::abs(x - reach) <= w)) {
        cv::dilate(mask, dilated_, kernel);  // not centred runs: OpenCV's own
        return;
      }
    }
    half_[static_cast<std::size_t>(j)] = w;
  }
  // Per row, the distance along it to the nearest set pixel, capped at 255.
  along_.create(mask.size(), CV_8U);
  for (int y = 0; y < mask.rows; ++y) {
    const std::uint8_t* in = mask.ptr<std::uint8_t>(y);
    std::uint8_t* d = along_.ptr<std::uint8_t>(y);
    int last = 255;
    for (int x = 0; x < mask.cols; ++x) {
      last = in[x] ? 0 : std::min(last + 1, 255);
      d[x] = static_cast<std::uint8_t>(last);
    }
    last = 255;
    for (int x = mask.cols - 1; x >= 0; --x) {
      last = in[x] ? 0 : std::min(last + 1, 255);
      d[x] = static_cast<std::uint8_t>(std::min<int>(d[x], last));
    }
  }
}

bool EllipseDilation::covers(int x, int y) const {
  if (!dilated_.empty()) return dilated_.at<std::uint8_t>(y, x) != 0;
  for (int j = 0; j <= 2 * reach_; ++j) {
    const int yy = y + j - reach_;
    if (yy >= 0 && yy < along_.rows && along_.at<std::uint8_t>(yy, x) <= half_[j]) return true;
  }
  return false;
}

}  // namespace sinew::rt::detail
