#pragma once
/// Small line plots for the tools' report pictures (PNG, OpenCV): a panel maps data to pixels and
/// draws its frame, grid and labels; save_png writes atomically. Used by sinew-register's
/// convergence plots and sinew-track's whisker time series.

#include <opencv2/core.hpp>
#include <string>

namespace sinew::tools::plot {

const cv::Scalar kInk(40, 40, 40), kGrid(220, 220, 220), kBlue(200, 90, 30), kRed(40, 40, 210),
    kGreen(60, 160, 60);

/// Three significant digits.
std::string number(double v);

void text(cv::Mat& image, const std::string& s, cv::Point at, double size = 0.45,
          cv::Scalar colour = kInk);

/// Encodes a PNG, writes a temporary file and renames it. False with error when it cannot.
bool save_png(const std::string& path, const cv::Mat& image, std::string* error);

/// A panel's frame: plot area in pixels for data [u0, u1] x [v0, v1].
struct Panel {
  cv::Rect area;
  double u0, u1, v0, v1;
  cv::Point at(double u, double v) const;
  /// Frame, horizontal grid lines (log scales: one per decade, v0 and v1 whole decades; linear:
  /// quarters) with their values, and the title above.
  void axes(cv::Mat& image, const std::string& title, bool log_v) const;
};

}  // namespace sinew::tools::plot
