#pragma once
/// A read-only view of an 8-bit grey image that the caller owns (camera buffer, cv::Mat, ...):
/// no copy, no ownership. The tracker reads only the pixels along its search lines.

#include <cmath>
#include <cstddef>
#include <cstdint>

namespace sinew::rt {

struct ImageView {
  const std::uint8_t* data = nullptr;  ///< first pixel of row 0
  int width = 0;                       ///< pixels
  int height = 0;                      ///< pixels
  std::ptrdiff_t stride = 0;           ///< bytes from one row to the next (≥ width)

  bool valid() const { return data && width > 1 && height > 1 && stride >= width; }

  /// Bilinear interpolation at (x, y) in pixel coordinates (pixel centres at integers). Returns
  /// false, leaving *value untouched, when (x, y) is outside [0, width−1] x [0, height−1].
  bool sample(double x, double y, float* value) const {
    if (!(x >= 0.0 && y >= 0.0 && x <= width - 1.0 && y <= height - 1.0)) return false;
    int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
    if (x0 >= width - 1) x0 = width - 2;
    if (y0 >= height - 1) y0 = height - 2;
    const float fx = static_cast<float>(x - x0), fy = static_cast<float>(y - y0);
    const std::uint8_t* p = data + y0 * stride + x0;
    const float top = p[0] + fx * (p[1] - p[0]);
    const float bottom = p[stride] + fx * (p[stride + 1] - p[stride]);
    *value = top + fy * (bottom - top);
    return true;
  }
};

}  // namespace sinew::rt
