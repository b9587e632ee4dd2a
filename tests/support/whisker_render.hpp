#pragma once
/// Whisker scenes for rt tests, without OpenCV: a graded backlight, a dark face (a disc at the
/// left border), curved tapered whiskers that darken the backlight by a few grey levels, dark
/// rods and blocks, and Gaussian noise (tests/support/beam_render.hpp's add_noise).

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "tests/support/beam_render.hpp"

namespace sinew::testing {

/// A whisker of the scene: from its follicle at `angle` (rad, from +x towards +y), curvature
/// `kappa` (1/px, constant), `length` px; darkens the backlight by `contrast` grey levels at the
/// follicle, falling linearly to 40 % of that at the tip; width 3 px at the follicle, 1 px at the
/// tip.
struct SceneWhisker {
  Eigen::Vector2d follicle = Eigen::Vector2d::Zero();
  double angle = 0.0;
  double kappa = 0.0;
  double length = 100.0;
  double contrast = 10.0;

  /// Points every 0.5 px from the follicle to the tip.
  std::vector<Eigen::Vector2d> points() const {
    std::vector<Eigen::Vector2d> pts;
    const int n = static_cast<int>(std::ceil(length / 0.5));
    for (int k = 0; k <= n; ++k) {
      const double s = length * k / n;
      // Arc of constant curvature: exact positions.
      const double a = angle + kappa * s;
      Eigen::Vector2d p = follicle;
      if (std::abs(kappa) < 1e-12) {
        p += s * Eigen::Vector2d(std::cos(angle), std::sin(angle));
      } else {
        p += Eigen::Vector2d(std::sin(a) - std::sin(angle), std::cos(angle) - std::cos(a)) / kappa;
      }
      pts.push_back(p);
    }
    return pts;
  }
};

/// Backlight 140 + 50·x/width (+ a little vertical shading), the face as a disc of grey 25.
inline GreyImage backlit_face(int width, int height, const Eigen::Vector2d& face_centre,
                              double face_radius) {
  GreyImage img(width, height, 0);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const double back = 140.0 + 50.0 * x / width + 10.0 * std::sin(M_PI * y / height);
      const double d = std::hypot(x - face_centre.x(), y - face_centre.y()) - face_radius;
      const double cover = std::clamp(0.5 - d, 0.0, 1.0);
      img.pixels[std::size_t(y) * width + x] =
          static_cast<std::uint8_t>(std::lround(back * (1.0 - cover) + 25.0 * cover));
    }
  }
  return img;
}

/// Darkens the image along a whisker (anti-aliased, tapered; the darkest sample wins per pixel
/// within this whisker, whiskers add up where they cross).
inline void draw_whisker(GreyImage& img, const SceneWhisker& w) {
  std::vector<float> dark(img.pixels.size(), 0.0f);
  const auto pts = w.points();
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const double s = w.length * i / (pts.size() - 1);
    const double hw = 0.5 * (3.0 - 2.0 * s / w.length);
    const double c = w.contrast * (1.0 - 0.6 * s / w.length);
    const Eigen::Vector2d& p = pts[i];
    for (int y = std::max(0, int(p.y() - 3)); y <= std::min(img.height - 1, int(p.y() + 3)); ++y) {
      for (int x = std::max(0, int(p.x() - 3)); x <= std::min(img.width - 1, int(p.x() + 3)); ++x) {
        const double cover = std::clamp(hw + 0.5 - std::hypot(x - p.x(), y - p.y()), 0.0, 1.0);
        float& d = dark[std::size_t(y) * img.width + x];
        d = std::max(d, static_cast<float>(c * cover));
      }
    }
  }
  for (std::size_t k = 0; k < dark.size(); ++k) {
    const double v = img.pixels[k] - dark[k];
    img.pixels[k] = static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0, 255.0)));
  }
}

/// Distance from p to the polyline pts (the true curve of a whisker, for scoring a fit).
inline double distance_to_polyline(const std::vector<Eigen::Vector2d>& pts,
                                   const Eigen::Vector2d& p) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i + 1 < pts.size(); ++i) {
    const Eigen::Vector2d a = pts[i], ab = pts[i + 1] - pts[i];
    const double t = std::clamp((p - a).dot(ab) / std::max(ab.squaredNorm(), 1e-12), 0.0, 1.0);
    best = std::min(best, (a + t * ab - p).norm());
  }
  return best;
}

/// A dark straight rod of the given half width and grey level from a to b.
inline void draw_rod(GreyImage& img, const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                     double half_width, std::uint8_t ink) {
  std::vector<Eigen::Vector2d> pts;
  const int n = static_cast<int>(std::ceil((b - a).norm() / 0.5));
  for (int k = 0; k <= n; ++k) pts.push_back(a + (b - a) * (double(k) / n));
  draw_band(img, pts, half_width, ink);
}

}  // namespace sinew::testing
