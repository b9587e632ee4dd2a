// rt::taper_length: a whisker's whole length from how its drawn darkness falls along the part
// that is tracked (rt/whisker/taper_length.hpp).
#include "rt/whisker/taper_length.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "tests/support/beam_render.hpp"

namespace sinew::rt {
namespace {

using sinew::testing::GreyImage;

// A straight whisker on a backlight of 200 from (60, 150) at −20°, L px long, its width falling
// linearly from `base_width` px at the follicle to base_width · tip_to_base at the tip (a cone),
// drawn by its exact area coverage of each pixel (supersampled 4 × 4), 60 grey levels dark where
// it covers a pixel, with Gaussian noise σ. `taper` false: the same width all along (a rod).
GreyImage draw(double length, double base_width, double tip_to_base, bool taper, double sigma) {
  GreyImage img(400, 300, 200);
  const Eigen::Vector2d follicle(60.0, 150.0);
  const Eigen::Vector2d t(std::cos(-20.0 * M_PI / 180.0), std::sin(-20.0 * M_PI / 180.0));
  std::mt19937 gen(11);
  std::normal_distribution<double> noise(0.0, sigma);
  for (int y = 0; y < img.height; ++y) {
    for (int x = 0; x < img.width; ++x) {
      double covered = 0.0;
      for (int k = 0; k < 16; ++k) {
        const Eigen::Vector2d p(x - 0.375 + 0.25 * (k % 4), y - 0.375 + 0.25 * (k / 4));
        const double s = (p - follicle).dot(t);
        const double across = std::abs((p - follicle).x() * t.y() - (p - follicle).y() * t.x());
        if (s < 0.0 || s > length) continue;
        const double width =
            taper ? base_width * (1.0 - (1.0 - tip_to_base) * s / length) : base_width;
        covered += across <= 0.5 * width ? 1.0 / 16.0 : 0.0;
      }
      const double v = 200.0 - 60.0 * covered + noise(gen);
      img.pixels[std::size_t(y) * img.width + x] =
          static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
    }
  }
  return img;
}

// Nodes every 10 px along the whisker's first `tracked` px.
Eigen::Matrix2Xd nodes(double tracked) {
  const Eigen::Vector2d follicle(60.0, 150.0);
  const Eigen::Vector2d t(std::cos(-20.0 * M_PI / 180.0), std::sin(-20.0 * M_PI / 180.0));
  const int n = static_cast<int>(tracked / 10.0) + 1;
  Eigen::Matrix2Xd X(2, n);
  for (int i = 0; i < n; ++i) X.col(i) = follicle + (tracked * i / (n - 1)) * t;
  return X;
}

// A cone 220 px long (4 px wide at the follicle, tip 1/20 of that, as the shared renderer's 40
// and 2 µm at 0.02 mm/px), tracked over its first 160 px (0.73 of it, as a faint tip is lost):
// its length within 5 % (measured 221.1 and 225.6 px), at noise σ 2 and 4; the tracked length
// alone is 27 % short.
TEST(TaperLength, AConesLengthFromItsDarknessAlongItsTrackedPart) {
  for (double sigma : {2.0, 4.0}) {
    SCOPED_TRACE("sigma " + std::to_string(sigma));
    const GreyImage img = draw(220.0, 4.0, 0.05, true, sigma);
    const TaperLength L = taper_length(img.view(), nodes(160.0), 0.05);
    EXPECT_TRUE(L.measured);
    EXPECT_NEAR(L.tracked_px, 160.0, 1e-9);
    EXPECT_NEAR(L.length_px, 220.0, 0.05 * 220.0) << L.samples << " samples";
    EXPECT_GE(L.samples, 50);
  }
}

// A rod of one width (no taper: the darkness does not fall) and a whisker too short to fit keep
// the tracked length, not measured.
TEST(TaperLength, ARodOrAShortTraceKeepsTheTrackedLength) {
  const GreyImage rod = draw(220.0, 3.0, 1.0, false, 2.0);
  const TaperLength a = taper_length(rod.view(), nodes(160.0), 0.05);
  EXPECT_FALSE(a.measured);
  EXPECT_EQ(a.length_px, a.tracked_px);
  const GreyImage cone = draw(220.0, 4.0, 0.05, true, 2.0);
  const TaperLength b = taper_length(cone.view(), nodes(20.0), 0.05);
  EXPECT_FALSE(b.measured);
  EXPECT_NEAR(b.length_px, 20.0, 1e-9);
}

}  // namespace
}  // namespace sinew::rt
