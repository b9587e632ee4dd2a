#include "tools/track/whisker_plots.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <opencv2/imgproc.hpp>

#include "tools/io/png_plot.hpp"

namespace sinew::tools {

using namespace plot;

namespace {

// One panel of a series over the frames: a line through the finite values, broken at NaN.
void draw_series(cv::Mat& image, const cv::Rect& area, const std::vector<int>& frames,
                 const std::vector<double>& values, const std::string& title) {
  double lo = INFINITY, hi = -INFINITY;
  for (double v : values) {
    if (!std::isfinite(v)) continue;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  if (!std::isfinite(lo)) lo = 0.0, hi = 1.0;
  if (!(hi > lo)) {
    const double pad = std::max(std::abs(lo) * 0.1, 1e-30);
    lo -= pad;
    hi += pad;
  }
  const double f0 = frames.empty() ? 0.0 : frames.front();
  const double f1 = frames.empty() ? 1.0 : std::max<double>(frames.back(), f0 + 1.0);
  const Panel panel{area, f0, f1, lo, hi};
  panel.axes(image, title, false);
  text(image, number(f0), {area.x, area.y + area.height + 16}, 0.4);
  text(image, number(f1), {area.x + area.width - 30, area.y + area.height + 16}, 0.4);
  for (std::size_t i = 1; i < values.size(); ++i) {
    if (!std::isfinite(values[i - 1]) || !std::isfinite(values[i])) continue;
    cv::line(image, panel.at(frames[i - 1], values[i - 1]), panel.at(frames[i], values[i]), kBlue,
             1, cv::LINE_AA);
  }
}

}  // namespace

bool write_whisker_plots(const std::string& dir, const std::vector<WhiskerSeries>& series,
                         const std::string& curvature_unit, const std::string& moment_unit,
                         std::string* error) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    if (error != nullptr) *error = dir + ": cannot create the folder (" + ec.message() + ")";
    return false;
  }
  for (const WhiskerSeries& s : series) {
    cv::Mat image(820, 900, CV_8UC3, cv::Scalar(255, 255, 255));
    const std::string id = "whisker " + std::to_string(s.id) + ": ";
    draw_series(image, cv::Rect(90, 40, 780, 170), s.frame, s.base_angle_deg,
                id + "base angle, degrees");
    draw_series(image, cv::Rect(90, 260, 780, 170), s.frame, s.delta_curvature,
                id + "curvature change from rest, " + curvature_unit);
    draw_series(image, cv::Rect(90, 480, 780, 170), s.frame, s.moment,
                id + "moment at the follicle, " + moment_unit);
    draw_series(image, cv::Rect(90, 700, 780, 60), s.frame, s.contact,
                id + "contact with an object (1: touching)");
    text(image, "frame (gaps: lost)", {400, 805}, 0.45);
    if (!save_png(dir + "/whisker_" + std::to_string(s.id) + ".png", image, error)) return false;
  }
  return true;
}

}  // namespace sinew::tools
