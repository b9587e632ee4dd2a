#pragma once
/// The chessboard distance of every pixel to the nearest zero pixel of a mask, as
/// cv::distanceTransform(mask, DIST_C, 3) computes it (exact for that metric), but in bytes and
/// into a buffer the caller keeps: whisker detection asks it on every frame to know how deep inside
/// the dark regions each pixel lies, and skips the ridge measure where no stage reads it.

#include <opencv2/core.hpp>

namespace sinew::rt::detail {

/// mask: CV_8U, non-zero = inside. depth: CV_8U of the mask's size (re-created only when its size
/// or type differ), max(|dx|, |dy|) to the nearest zero pixel of the mask, 0 on zero pixels,
/// capped at 255 (also where the mask has no zero pixel).
void chessboard_distance(const cv::Mat& mask, cv::Mat& depth);

}  // namespace sinew::rt::detail
