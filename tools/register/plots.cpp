#include "tools/register/plots.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace sinew::tools {
namespace {

const cv::Scalar kInk(40, 40, 40), kGrid(220, 220, 220), kBlue(200, 90, 30), kRed(40, 40, 210),
    kGreen(60, 160, 60);

std::string number(double v) {
  char s[32];
  std::snprintf(s, sizeof(s), "%.3g", v);
  return s;
}

void text(cv::Mat& image, const std::string& s, cv::Point at, double size = 0.45,
          cv::Scalar colour = kInk) {
  cv::putText(image, s, at, cv::FONT_HERSHEY_SIMPLEX, size, colour, 1, cv::LINE_AA);
}

// Atomic PNG: encode, write a temporary file, rename.
bool save(const std::string& path, const cv::Mat& image, std::string* error) {
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

// A panel's frame: plot area [x0, x1] x [y0, y1] in pixels for data [u0, u1] x [v0, v1].
struct Panel {
  cv::Rect area;
  double u0, u1, v0, v1;
  cv::Point at(double u, double v) const {
    const double x = area.x + (u - u0) / std::max(u1 - u0, 1e-300) * area.width;
    const double y = area.y + area.height - (v - v0) / std::max(v1 - v0, 1e-300) * area.height;
    return {static_cast<int>(std::lround(x)), static_cast<int>(std::lround(y))};
  }
  void axes(cv::Mat& image, const std::string& title, bool log_v) const {
    cv::rectangle(image, area, kInk, 1);
    // Log scales: one line per decade (v0, v1 are whole decades); linear: quarters.
    const int steps = log_v ? std::max(1, static_cast<int>(std::lround(v1 - v0))) : 4;
    for (int k = 0; k <= steps; ++k) {
      const double v = v0 + (v1 - v0) * k / steps;
      const cv::Point p = at(u0, v);
      cv::line(image, p, at(u1, v), kGrid, 1);
      text(image, log_v ? "1e" + number(v) : number(v), {5, p.y + 4}, 0.4);
    }
    text(image, title, {area.x, area.y - 8}, 0.5);
  }
};

}  // namespace

bool write_error_histogram_png(const std::string& path, const std::vector<double>& errors,
                               const std::string& unit, std::string* error) {
  cv::Mat image(360, 560, CV_8UC3, cv::Scalar(255, 255, 255));
  const double largest = errors.empty() ? 1.0 : *std::max_element(errors.begin(), errors.end());
  const double top = largest > 0.0 ? largest : 1.0;
  constexpr int kBins = 20;
  std::vector<int> counts(kBins, 0);
  double mean = 0.0;
  for (double e : errors) {
    ++counts[static_cast<std::size_t>(std::min(kBins - 1, static_cast<int>(e / top * kBins)))];
    mean += e / static_cast<double>(std::max<std::size_t>(errors.size(), 1));
  }
  const int most = std::max(1, *std::max_element(counts.begin(), counts.end()));
  const Panel panel{cv::Rect(70, 40, 460, 260), 0.0, top, 0.0, static_cast<double>(most)};
  panel.axes(image, "marker errors (" + std::to_string(errors.size()) + " markers), " + unit,
             false);
  for (int b = 0; b < kBins; ++b) {
    cv::rectangle(image, panel.at(top * b / kBins, counts[static_cast<std::size_t>(b)]),
                  panel.at(top * (b + 1) / kBins, 0.0), kBlue, cv::FILLED);
  }
  cv::line(image, panel.at(mean, 0), panel.at(mean, most), kRed, 2);
  text(image, "mean " + number(mean), panel.at(mean, most) + cv::Point(4, 14), 0.45, kRed);
  for (int k = 0; k <= 4; ++k) {
    text(image, number(top * k / 4.0),
         panel.at(top * k / 4.0, 0) + cv::Point(k == 4 ? -40 : -10, 18), 0.4);
  }
  text(image, "error (" + unit + "), max " + number(largest), {220, 345}, 0.45);
  return save(path, image, error);
}

bool write_convergence_png(const std::string& path,
                           const std::vector<offline::GaussNewtonIteration>& iterations,
                           double scale, const std::string& unit, std::string* error) {
  cv::Mat image(520, 640, CV_8UC3, cv::Scalar(255, 255, 255));
  const auto n = static_cast<double>(std::max<std::size_t>(iterations.size(), 2) - 1);
  auto log10_of = [](double v) { return std::log10(std::max(v, 1e-300)); };
  auto range = [&](auto&& value) {
    double lo = INFINITY, hi = -INFINITY;
    for (const auto& it : iterations) {
      lo = std::min(lo, value(it));
      hi = std::max(hi, value(it));
    }
    if (!(hi > lo)) hi = lo + 1.0;
    return std::pair{std::floor(lo), std::ceil(hi)};
  };
  const auto [o0, o1] = range([&](const auto& it) { return log10_of(it.objective); });
  const auto [e0, e1] = range([&](const auto& it) {
    return std::max(log10_of(it.marker_error_max * scale), log10_of(it.marker_error_mean * scale));
  });
  const auto [m0, m1] =
      range([&](const auto& it) { return log10_of(it.marker_error_mean * scale); });
  const Panel top{cv::Rect(70, 40, 540, 180), 0.0, n, o0, o1};
  const Panel bottom{cv::Rect(70, 290, 540, 180), 0.0, n, std::min(e0, m0), std::max(e1, m1)};
  top.axes(image, "objective (log scale)", true);
  bottom.axes(image, "marker error mean (blue) and max (red), " + unit + " (log scale)", true);
  for (std::size_t i = 0; i < iterations.size(); ++i) {
    const double u = static_cast<double>(i);
    if (i == 0 || iterations[i].stage != iterations[i - 1].stage) {
      for (const Panel* p : {&top, &bottom})
        cv::line(image, p->at(u, p->v0), p->at(u, p->v1), kGreen, 1);
      text(image, offline::to_string(iterations[i].stage), top.at(u, top.v1) + cv::Point(3, 14),
           0.4, kGreen);
    }
    if (i == 0) continue;
    const auto& a = iterations[i - 1];
    const auto& b = iterations[i];
    cv::line(image, top.at(u - 1, log10_of(a.objective)), top.at(u, log10_of(b.objective)), kInk, 2,
             cv::LINE_AA);
    cv::line(image, bottom.at(u - 1, log10_of(a.marker_error_mean * scale)),
             bottom.at(u, log10_of(b.marker_error_mean * scale)), kBlue, 2, cv::LINE_AA);
    cv::line(image, bottom.at(u - 1, log10_of(a.marker_error_max * scale)),
             bottom.at(u, log10_of(b.marker_error_max * scale)), kRed, 2, cv::LINE_AA);
  }
  text(image,
       "iteration (" + std::to_string(iterations.size()) + " rows: initial fit, then Gauss-Newton)",
       {150, 505}, 0.45);
  return save(path, image, error);
}

}  // namespace sinew::tools
