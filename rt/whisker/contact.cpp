#include "rt/whisker/contact.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace sinew::rt {

namespace {

// Bilinear lookup; far (255) outside the map.
double lookup(const float* d, int width, int height, const Eigen::Vector2d& p) {
  if (!(p.x() >= 0.0 && p.y() >= 0.0 && p.x() <= width - 1.0 && p.y() <= height - 1.0))
    return 255.0;
  const int x0 = std::min(static_cast<int>(p.x()), width - 2);
  const int y0 = std::min(static_cast<int>(p.y()), height - 2);
  const double fx = p.x() - x0, fy = p.y() - y0;
  const float* r0 = d + static_cast<std::ptrdiff_t>(y0) * width + x0;
  const float* r1 = r0 + width;
  return (1.0 - fy) * ((1.0 - fx) * r0[0] + fx * r0[1]) + fy * ((1.0 - fx) * r1[0] + fx * r1[1]);
}

}  // namespace

WhiskerContact find_contact(const Tracker& whisker, const float* distance, int width, int height,
                            double touch_px, double skip_px) noexcept {
  WhiskerContact c;
  c.distance_px = std::numeric_limits<double>::infinity();
  if (distance == nullptr || width < 2 || height < 2) return c;
  const common::BeamModel& model = whisker.model();
  double s0 = 0.0;
  double run_least = std::numeric_limits<double>::infinity();
  bool run_over = false;  // the first stretch within touch_px has ended
  for (int e = 0; e < model.num_elements(); ++e) {
    const double length = model.element(e).length;
    const int steps = std::max(1, static_cast<int>(std::ceil(length)));
    for (int k = 0; k <= steps; ++k) {
      const double s = s0 + length * k / steps;
      if (s < skip_px) continue;
      const Eigen::Vector2d p = whisker.centreline(e, static_cast<double>(k) / steps).position;
      const double d = lookup(distance, width, height, p);
      c.distance_px = std::min(c.distance_px, d);
      if (d > touch_px) {
        run_over = run_over || c.touching;
      } else if (!run_over && d < run_least) {
        // The closest approach of the first stretch that touches: where a whisker bent around a
        // pole presses on it (the stretch's first point lies ~5 px before it on an 8 px pole).
        c.touching = true;
        run_least = d;
        c.arc_length_px = s;
        c.point = p;
      }
    }
    s0 += length;
  }
  return c;
}

Eigen::Vector2d away_from_objects(const float* distance, int width, int height,
                                  const Eigen::Vector2d& p) noexcept {
  if (distance == nullptr || width < 2 || height < 2) return Eigen::Vector2d::Zero();
  const Eigen::Vector2d ex(1.0, 0.0), ey(0.0, 1.0);
  const double gx =
      lookup(distance, width, height, p + ex) - lookup(distance, width, height, p - ex);
  const double gy =
      lookup(distance, width, height, p + ey) - lookup(distance, width, height, p - ey);
  if (!(std::abs(gx) < 255.0 && std::abs(gy) < 255.0)) return Eigen::Vector2d::Zero();
  return 0.5 * Eigen::Vector2d(gx, gy);
}

}  // namespace sinew::rt
