#include "rt/whisker/taper_length.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace sinew::rt {

namespace {

// Profiles every this many pixels along the whisker, from a tenth of its length (the follicle's
// first pixels sit on the face's edge and its fur) to 2 px before its tracked end.
constexpr double kStepPx = 2.0;
// Across the whisker: the deficit integrated within ±3 px, the backlight the median of the
// samples between 4 and 6 px on either side (a whisker is at most ~4 px wide on these cameras).
constexpr double kCorePx = 3.0, kSidePx = 4.0, kOuterPx = 6.0, kAcrossStepPx = 0.25;

double median(std::vector<double>& v) {
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// The least-squares line y = a + c·s through the points with w = 1.
bool fit_line(const std::vector<double>& s, const std::vector<double>& y,
              const std::vector<char>& use, double* a, double* c) {
  double n = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (!use[i]) continue;
    n += 1;
    sx += s[i];
    sy += y[i];
    sxx += s[i] * s[i];
    sxy += s[i] * y[i];
  }
  const double det = n * sxx - sx * sx;
  if (n < 2 || !(det > 0)) return false;
  *c = (n * sxy - sx * sy) / det;
  *a = (sy - *c * sx) / n;
  return true;
}

}  // namespace

TaperLength taper_length(const ImageView& frame, const Eigen::Matrix2Xd& centreline,
                         double tip_to_base) {
  TaperLength out;
  const Eigen::Index n = centreline.cols();
  std::vector<double> arc(static_cast<std::size_t>(std::max<Eigen::Index>(n, 1)), 0.0);
  for (Eigen::Index i = 1; i < n; ++i)
    arc[i] = arc[i - 1] + (centreline.col(i) - centreline.col(i - 1)).norm();
  out.tracked_px = arc.back();
  out.length_px = out.tracked_px;
  if (n < 2 || !frame.valid()) return out;

  std::vector<double> s_at, mass, side;
  std::vector<float> core;
  Eigen::Index e = 0;
  for (double s = 0.1 * out.tracked_px; s <= out.tracked_px - 2.0; s += kStepPx) {
    while (e + 2 < n && arc[e + 1] < s) ++e;
    const double le = arc[e + 1] - arc[e];
    if (!(le > 0)) continue;
    const Eigen::Vector2d t = (centreline.col(e + 1) - centreline.col(e)) / le;
    const Eigen::Vector2d p = centreline.col(e) + (s - arc[e]) * t;
    const Eigen::Vector2d normal(-t.y(), t.x());
    side.clear();
    core.clear();
    double deficit = 0.0;
    bool inside = true;
    for (double a = -kOuterPx; a <= kOuterPx + 1e-9 && inside; a += kAcrossStepPx) {
      const Eigen::Vector2d q = p + a * normal;
      float v = 0.0f;
      inside = frame.sample(q.x(), q.y(), &v);
      if (std::abs(a) >= kSidePx) side.push_back(v);
      if (std::abs(a) <= kCorePx) core.push_back(v);
    }
    if (!inside || side.empty()) continue;
    const double backlight = median(side);
    if (!(backlight > 0)) continue;
    for (float v : core) deficit += std::max(0.0, backlight - v) * kAcrossStepPx;
    s_at.push_back(s);
    mass.push_back(deficit / backlight);
  }
  if (s_at.size() < 10) return out;
  // A robust line: least squares, then three rounds without the points beyond 2.5 robust σ of
  // it (a neighbour or a crossing in one profile, a patch of fur).
  std::vector<char> use(s_at.size(), 1);
  double a = 0.0, c = 0.0;
  if (!fit_line(s_at, mass, use, &a, &c)) return out;
  std::vector<double> residual(s_at.size());
  for (int round = 0; round < 3; ++round) {
    for (std::size_t i = 0; i < s_at.size(); ++i) residual[i] = std::abs(mass[i] - a - c * s_at[i]);
    std::vector<double> r = residual;
    const double cut = 2.5 * 1.4826 * median(r) + 1e-12;
    for (std::size_t i = 0; i < s_at.size(); ++i) use[i] = residual[i] <= cut;
    if (!fit_line(s_at, mass, use, &a, &c)) return out;
  }
  out.samples = static_cast<int>(std::count(use.begin(), use.end(), 1));
  if (!(a > 0.0 && c < 0.0)) return out;
  // Zero line mass where the cone's radius would reach zero; the tip is short of it by the ratio.
  const double length = -a / c * (1.0 - std::clamp(tip_to_base, 0.0, 0.99));
  if (length >= out.tracked_px && length <= 2.0 * out.tracked_px) {
    out.length_px = length;
    out.measured = true;
  }
  return out;
}

}  // namespace sinew::rt
