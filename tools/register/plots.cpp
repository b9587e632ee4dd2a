#include "tools/register/plots.hpp"

#include "tools/io/png_plot.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace sinew::tools {

using namespace plot;

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
  return save_png(path, image, error);
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
  return save_png(path, image, error);
}

}  // namespace sinew::tools
