// Built against the installed Sinew package: renders a faint whisker leaving a dark face on a
// backlight, finds it with no initialisation, tracks it while it turns by 4 degrees, and checks
// the tip against the rendered one. Exit 0 on success.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <vector>

#include "rt/whisker/detection.hpp"
#include "rt/whisker/whisker_tracker.hpp"

namespace {

constexpr int kWidth = 320, kHeight = 240;
constexpr double kFollicleX = 40.0, kFollicleY = 120.0, kLength = 150.0;

// Face: x < 40; a straight whisker 1.5 px wide, 20 grey levels dark, at `angle` from +x.
std::vector<std::uint8_t> render(double angle) {
  std::vector<std::uint8_t> img(kWidth * kHeight);
  const double dx = std::cos(angle), dy = std::sin(angle);
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      double v = 170.0;
      if (x < kFollicleX) {
        v = 30.0;
      } else {
        const double px = x - kFollicleX, py = y - kFollicleY;
        const double along = px * dx + py * dy, across = std::abs(-px * dy + py * dx);
        if (along >= 0.0 && along <= kLength) v -= 20.0 * std::exp(-across * across / 1.1);
      }
      img[y * kWidth + x] = static_cast<std::uint8_t>(v);
    }
  }
  return img;
}

}  // namespace

int main() {
  const std::vector<std::uint8_t> first = render(0.1);
  const sinew::rt::ImageView view{first.data(), kWidth, kHeight, kWidth};
  sinew::rt::WhiskerDetectionOptions options;
  options.face = sinew::rt::FaceSide::kLeft;
  const sinew::rt::WhiskerDetection detection = sinew::rt::detect_whiskers(view, options);
  if (!detection.error.empty() || detection.whiskers.size() != 1) {
    std::printf("detection: %zu whiskers, %s\n", detection.whiskers.size(),
                detection.error.c_str());
    return 1;
  }
  sinew::rt::WhiskerTracker tracker({detection.whiskers[0].points});
  if (!tracker.valid()) {
    std::printf("tracker: %s\n", tracker.error().c_str());
    return 1;
  }
  double angle = 0.1;
  for (int frame = 0; frame < 5; ++frame, angle += 0.01) {
    const std::vector<std::uint8_t> img = render(angle);
    tracker.track(sinew::rt::ImageView{img.data(), kWidth, kHeight, kWidth});
  }
  angle -= 0.01;
  const Eigen::Vector2d tip = tracker.result(0).tip;
  const double length = tracker.result(0).length_px;
  const Eigen::Vector2d expected(kFollicleX + length * std::cos(angle),
                                 kFollicleY + length * std::sin(angle));
  const double miss = (tip - expected).norm();
  std::printf("status %s, tip (%.2f, %.2f), %.2f px from the rendered whisker\n",
              sinew::rt::to_string(tracker.result(0).status), tip.x(), tip.y(), miss);
  return tracker.result(0).status == sinew::rt::FrameStatus::kOk && miss < 1.0 ? 0 : 1;
}
