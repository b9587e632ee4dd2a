#pragma once
/// A small renderer for rt tests: draws a beam's centreline (a dense polyline) as a dark band or
/// line on a bright background with a 1-px anti-aliasing ramp, plus optional Gaussian noise. Tests
/// use it to make frames with known truth without OpenCV.

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "common/beam/beam_model.hpp"
#include "rt/centreline.hpp"
#include "rt/image_view.hpp"

namespace sinew::testing {

struct GreyImage {
  int width = 0, height = 0;
  std::vector<std::uint8_t> pixels;
  GreyImage(int w, int h, std::uint8_t value)
      : width(w), height(h), pixels(std::size_t(w) * h, value) {}
  rt::ImageView view() const { return {pixels.data(), width, height, width}; }
};

/// Dense points along a beam state's Hermite centreline (the true continuous shape when the state
/// comes from a fine static solve).
inline std::vector<Eigen::Vector2d> centreline_points(const common::BeamModel& model,
                                                      const Eigen::VectorXd& u, int per_element) {
  std::vector<Eigen::Vector2d> pts;
  const Eigen::Matrix2Xd T = rt::polyline_node_tangents(model.rest_positions());
  auto point = [&](int e, double xi) {
    return rt::hermite_centreline(model.rest_positions().col(e), model.element(e), T.col(e),
                                  T.col(e + 1), u.segment<6>(3 * e), xi)
        .position;
  };
  for (int e = 0; e < model.num_elements(); ++e) {
    for (int k = 0; k < per_element; ++k) pts.push_back(point(e, double(k) / per_element));
  }
  pts.push_back(point(model.num_elements() - 1, 1.0));
  return pts;
}

/// Draws the band {distance to the polyline ≤ half_width} with grey level `ink`: a pixel at
/// distance d from the polyline is covered by clamp(half_width + 0.5 − d, 0, 1). Each segment
/// visits only the pixels within reach of it, keeping the nearest distance per pixel.
inline void draw_band(GreyImage& img, const std::vector<Eigen::Vector2d>& pts, double half_width,
                      std::uint8_t ink) {
  if (pts.empty()) return;
  const double reach = half_width + 2.0;
  Eigen::Vector2d lo = pts[0], hi = pts[0];
  for (const auto& p : pts) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const int x0 = std::max(0, int(std::floor(lo.x() - reach))),
            x1 = std::min(img.width - 1, int(std::ceil(hi.x() + reach)));
  const int y0 = std::max(0, int(std::floor(lo.y() - reach))),
            y1 = std::min(img.height - 1, int(std::ceil(hi.y() + reach)));
  if (x0 > x1 || y0 > y1) return;
  const int w = x1 - x0 + 1;
  std::vector<double> nearest(std::size_t(w) * (y1 - y0 + 1), 1e30);  // squared distances
  for (std::size_t k = 0; k < pts.size(); ++k) {
    const Eigen::Vector2d a = pts[k], ab = k + 1 < pts.size() ? Eigen::Vector2d(pts[k + 1] - a)
                                                              : Eigen::Vector2d::Zero();
    const Eigen::Vector2d slo = a.cwiseMin(a + ab), shi = a.cwiseMax(a + ab);
    const int sx0 = std::max(x0, int(std::floor(slo.x() - reach))),
              sx1 = std::min(x1, int(std::ceil(shi.x() + reach)));
    const int sy0 = std::max(y0, int(std::floor(slo.y() - reach))),
              sy1 = std::min(y1, int(std::ceil(shi.y() + reach)));
    for (int y = sy0; y <= sy1; ++y) {
      for (int x = sx0; x <= sx1; ++x) {
        const Eigen::Vector2d q(x, y);
        const double t = std::clamp((q - a).dot(ab) / std::max(ab.squaredNorm(), 1e-12), 0.0, 1.0);
        double& best = nearest[std::size_t(y - y0) * w + (x - x0)];
        best = std::min(best, (a + t * ab - q).squaredNorm());
      }
    }
  }
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const double d = std::sqrt(nearest[std::size_t(y - y0) * w + (x - x0)]);
      const double cover = std::clamp(half_width + 0.5 - d, 0.0, 1.0);
      std::uint8_t& v = img.pixels[std::size_t(y) * img.width + x];
      v = static_cast<std::uint8_t>(std::lround(v + cover * (ink - double(v))));
    }
  }
}

inline void add_noise(GreyImage& img, double sigma, std::mt19937& gen) {
  std::normal_distribution<double> n(0.0, sigma);
  for (auto& v : img.pixels)
    v = static_cast<std::uint8_t>(std::clamp(std::lround(v + n(gen)), 0L, 255L));
}

}  // namespace sinew::testing
