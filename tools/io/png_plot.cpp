#include "tools/io/png_plot.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

namespace sinew::tools::plot {

std::string number(double v) {
  char s[32];
  std::snprintf(s, sizeof(s), "%.3g", v);
  return s;
}

void text(cv::Mat& image, const std::string& s, cv::Point at, double size, cv::Scalar colour) {
  cv::putText(image, s, at, cv::FONT_HERSHEY_SIMPLEX, size, colour, 1, cv::LINE_AA);
}

bool save_png(const std::string& path, const cv::Mat& image, std::string* error) {
  std::vector<unsigned char> bytes;
  if (!cv::imencode(".png", image, bytes)) {
    if (error != nullptr) *error = path + ": PNG encoding failed";
    return false;
  }
  const std::string tmp = path + ".tmp";
  FILE* f = std::fopen(tmp.c_str(), "wb");
  const bool ok = f != nullptr && std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size();
  if (f != nullptr && std::fclose(f) != 0) return false;
  std::error_code ec;
  if (ok) std::filesystem::rename(tmp, path, ec);
  if (!ok || ec) {
    if (error != nullptr) *error = path + ": cannot write";
    return false;
  }
  return true;
}

cv::Point Panel::at(double u, double v) const {
  const double x = area.x + (u - u0) / std::max(u1 - u0, 1e-300) * area.width;
  const double y = area.y + area.height - (v - v0) / std::max(v1 - v0, 1e-300) * area.height;
  return {static_cast<int>(std::lround(x)), static_cast<int>(std::lround(y))};
}

void Panel::axes(cv::Mat& image, const std::string& title, bool log_v) const {
  cv::rectangle(image, area, kInk, 1);
  const int steps = log_v ? std::max(1, static_cast<int>(std::lround(v1 - v0))) : 4;
  for (int k = 0; k <= steps; ++k) {
    const double v = v0 + (v1 - v0) * k / steps;
    const cv::Point p = at(u0, v);
    cv::line(image, p, at(u1, v), kGrid, 1);
    text(image, log_v ? "1e" + number(v) : number(v), {5, p.y + 4}, 0.4);
  }
  text(image, title, {area.x, area.y - 8}, 0.5);
}

}  // namespace sinew::tools::plot
