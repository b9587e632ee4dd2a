#include "tools/synth/renderer.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <vector>

namespace sinew::tools::synth {

namespace {

constexpr double kPi = 3.14159265358979323846;

/// Independent seeded streams for the background, the occluder texture and the noise.
cv::RNG stream(std::uint64_t seed, std::uint64_t index) {
  return cv::RNG(seed * 0x9E3779B97F4A7C15ULL + 0x632BE59BD9B4E019ULL * (index + 1));
}

/// Pixel box [x0, x1] x [y0, y1] around a set of points, grown by `reach`, clipped to the image.
/// Empty (x0 > x1 or y0 > y1) when it misses the image.
struct PixelBox {
  int x0 = 0, y0 = 0, x1 = -1, y1 = -1;
};

PixelBox box_around(const Eigen::Matrix2Xd& points, double reach, int width, int height) {
  PixelBox b;
  b.x0 = std::max(0, static_cast<int>(std::floor(points.row(0).minCoeff() - reach)));
  b.y0 = std::max(0, static_cast<int>(std::floor(points.row(1).minCoeff() - reach)));
  b.x1 = std::min(width - 1, static_cast<int>(std::ceil(points.row(0).maxCoeff() + reach)));
  b.y1 = std::min(height - 1, static_cast<int>(std::ceil(points.row(1).maxCoeff() + reach)));
  return b;
}

/// scene ← (1 − c)·scene + c·value, with c the coverage of one pixel.
inline void blend(float& pixel, double coverage, double value) {
  pixel = static_cast<float>((1.0 - coverage) * pixel + coverage * value);
}

}  // namespace

Renderer::Renderer(const SynthOptions& options, const Simulation& simulation)
    : options_(options), simulation_(simulation), noise_rng_(stream(options.seed, 2)) {
  const int W = options.width, H = options.height;
  // The camera moves the image by at most ~35 px of pan and rotation plus ~1% of perspective.
  if (options.camera_motion != CameraMotion::kNone) pad_ = 48 + std::max(W, H) / 10;
  const int CW = W + 2 * pad_, CH = H + 2 * pad_;
  cv::RNG rng = stream(options.seed, 0);

  // Mild low-frequency shading: two waves of under one period across the image, ±16 grey levels.
  const double a1 = rng.uniform(0.3, 0.8), a2 = rng.uniform(0.2, 0.6),
               p1 = rng.uniform(0.0, 2 * kPi);
  const double b1 = rng.uniform(0.2, 0.6), b2 = rng.uniform(0.3, 0.8),
               p2 = rng.uniform(0.0, 2 * kPi);
  cv::Mat background8(CH, CW, CV_8U);
  for (int cy = 0; cy < CH; ++cy) {
    auto* row = background8.ptr<unsigned char>(cy);
    const double y = cy - pad_;
    for (int cx = 0; cx < CW; ++cx) {
      const double x = cx - pad_;
      const double v = kBackgroundGrey + 10.0 * std::sin(2 * kPi * (a1 * x / W + a2 * y / H) + p1) +
                       6.0 * std::cos(2 * kPi * (b1 * x / W - b2 * y / H) + p2);
      row[cx] = cv::saturate_cast<unsigned char>(v);
    }
  }

  // Clutter: straight segments fixed over the sequence, behind the beam. Every other one passes
  // through a point of the beam on a random frame, so some cross it; the rest lie anywhere.
  // OpenCV anti-aliases lines only on 8-bit images, hence the 8-bit background.
  const int shift = 4;  // sub-pixel endpoints, 1/16 px
  const double scale = 1 << shift;
  const int num_frames = static_cast<int>(simulation.frames.size());
  for (int i = 0; i < options.clutter; ++i) {
    Eigen::Vector2d mid;
    if (i % 2 == 0) {
      const Eigen::Matrix2Xd& c = simulation.frames[rng.uniform(0, num_frames)].centreline;
      const int last = static_cast<int>(c.cols()) - 1;
      mid = c.col(rng.uniform(last / 8, last + 1));
    } else {
      mid = Eigen::Vector2d(rng.uniform(0.0, 1.0 * W), rng.uniform(0.0, 1.0 * H));
    }
    const double angle = rng.uniform(0.0, kPi);
    const double half_length = 0.5 * rng.uniform(0.15, 0.45) * std::min(W, H);
    const Eigen::Vector2d d = half_length * Eigen::Vector2d(std::cos(angle), std::sin(angle));
    const bool dark = rng.uniform(0, 2) == 0;
    const double grey = dark ? rng.uniform(30.0, 120.0) : rng.uniform(225.0, 255.0);
    const int thickness = rng.uniform(1, 4);
    auto fixed_point = [this, scale](const Eigen::Vector2d& p) {
      return cv::Point(static_cast<int>(std::lround((p.x() + pad_) * scale)),
                       static_cast<int>(std::lround((p.y() + pad_) * scale)));
    };
    cv::line(background8, fixed_point(mid - d), fixed_point(mid + d), cv::Scalar(grey), thickness,
             cv::LINE_AA, shift);
  }
  background8.convertTo(background_, CV_32F);

  // Occluder texture: mid-grey with 16-px blocks (±25) and fine blurred noise, fixed in the scene.
  if (options.occluder) {
    cv::RNG texture_rng = stream(options.seed, 1);
    cv::Mat blocks((CH + 15) / 16, (CW + 15) / 16, CV_32F);
    texture_rng.fill(blocks, cv::RNG::UNIFORM, -25.0, 25.0);
    cv::Mat coarse;
    cv::resize(blocks, coarse, cv::Size(blocks.cols * 16, blocks.rows * 16), 0, 0,
               cv::INTER_NEAREST);
    cv::Mat fine(CH, CW, CV_32F);
    texture_rng.fill(fine, cv::RNG::NORMAL, 0.0, 60.0);
    cv::GaussianBlur(fine, fine, cv::Size(0, 0), 1.5);
    occluder_texture_ = coarse(cv::Rect(0, 0, CW, CH)) + fine + kOccluderGrey;
  }
}

void Renderer::draw_beam(cv::Mat& canvas, const Eigen::Matrix2Xd& centreline) const {
  // Coverage of a pixel centred at distance d from the centreline: a linear 1-px ramp,
  // c = clamp(w + 0.5 − d, 0, 1), so the band's area is right to first order.
  const double w = options_.half_width_px, reach = w + 1.0;
  const PixelBox box = box_around(centreline, reach, canvas.cols, canvas.rows);
  if (box.x0 > box.x1 || box.y0 > box.y1) return;
  const int bw = box.x1 - box.x0 + 1, bh = box.y1 - box.y0 + 1;
  std::vector<double> distance(static_cast<std::size_t>(bw) * bh,
                               std::numeric_limits<double>::infinity());
  for (Eigen::Index j = 0; j + 1 < centreline.cols(); ++j) {
    const Eigen::Vector2d a = centreline.col(j), b = centreline.col(j + 1), ab = b - a;
    const double ab2 = std::max(ab.squaredNorm(), 1e-300);
    const PixelBox s = box_around(centreline.middleCols<2>(j), reach, canvas.cols, canvas.rows);
    for (int y = s.y0; y <= s.y1; ++y) {
      for (int x = s.x0; x <= s.x1; ++x) {
        const Eigen::Vector2d ap = Eigen::Vector2d(x, y) - a;
        const double t = std::clamp(ap.dot(ab) / ab2, 0.0, 1.0);
        double& best = distance[static_cast<std::size_t>(y - box.y0) * bw + (x - box.x0)];
        best = std::min(best, (ap - t * ab).norm());
      }
    }
  }
  for (int y = box.y0; y <= box.y1; ++y) {
    float* row = canvas.ptr<float>(y);
    for (int x = box.x0; x <= box.x1; ++x) {
      const double d = distance[static_cast<std::size_t>(y - box.y0) * bw + (x - box.x0)];
      const double coverage = std::clamp(w + 0.5 - d, 0.0, 1.0);
      if (coverage > 0.0) blend(row[x], coverage, kBeamGrey);
    }
  }
}

void Renderer::draw_occluder(cv::Mat& canvas, const Eigen::Matrix2Xd& centreline) const {
  // A rectangle over the beam from 40% to 60% of its current arc length (never the base or the
  // tip), long side along the chord of that stretch, wide enough for its sag and the band.
  const Eigen::Index m = centreline.cols();
  std::vector<double> arc(static_cast<std::size_t>(m), 0.0);
  double total = 0.0;
  for (Eigen::Index j = 1; j < m; ++j) {
    total += (centreline.col(j) - centreline.col(j - 1)).norm();
    arc[j] = total;
  }
  auto point_at = [&](double s) {
    Eigen::Index j = 0;
    while (j + 2 < m && arc[j + 1] < s) ++j;
    const double t = std::clamp((s - arc[j]) / (arc[j + 1] - arc[j]), 0.0, 1.0);
    return Eigen::Vector2d((1 - t) * centreline.col(j) + t * centreline.col(j + 1));
  };
  const double s0 = 0.4 * total, s1 = 0.6 * total;
  const Eigen::Vector2d a = point_at(s0), b = point_at(s1);
  const double length = (b - a).norm();
  const Eigen::Vector2d along = (b - a) / length, across(-along.y(), along.x());
  double sag = 0.0;
  for (Eigen::Index j = 0; j < m; ++j) {
    if (arc[j] > s0 && arc[j] < s1)
      sag = std::max(sag, std::abs((centreline.col(j) - a).dot(across)));
  }
  const double half_height = options_.half_width_px + sag + 6.0;

  Eigen::Matrix2Xd corners(2, 4);
  corners << a + half_height * across, a - half_height * across, b + half_height * across,
      b - half_height * across;
  const PixelBox box = box_around(corners, 1.0, canvas.cols, canvas.rows);
  for (int y = box.y0; y <= box.y1; ++y) {
    float* row = canvas.ptr<float>(y);
    const float* texture = occluder_texture_.ptr<float>(y);
    for (int x = box.x0; x <= box.x1; ++x) {
      const Eigen::Vector2d ap = Eigen::Vector2d(x, y) - a;
      const double u = ap.dot(along), v = std::abs(ap.dot(across));
      const double coverage =
          std::clamp(std::min({u + 0.5, length - u + 0.5, half_height - v + 0.5}), 0.0, 1.0);
      if (coverage > 0.0) blend(row[x], coverage, texture[x]);
    }
  }
}

cv::Mat Renderer::render_canvas(int frame) const {
  cv::Mat canvas = background_.clone();
  const Eigen::Matrix2Xd centreline =
      simulation_.frames[frame].centreline.array() + static_cast<double>(pad_);
  if (!(options_.vanish && options_.vanish->contains(frame))) draw_beam(canvas, centreline);
  if (options_.occluder && options_.occluder->contains(frame)) draw_occluder(canvas, centreline);
  return canvas;
}

cv::Mat Renderer::render(int frame) {
  const cv::Mat canvas = render_canvas(frame);
  const cv::Size size(options_.width, options_.height);
  cv::Mat image;
  if (options_.camera_motion == CameraMotion::kNone) {
    image = canvas(cv::Rect(pad_, pad_, size.width, size.height)).clone();
  } else {
    // Canvas → reference pixels (−pad_) → frame pixels (H): the forward map warpPerspective wants.
    Eigen::Matrix3d from_canvas = Eigen::Matrix3d::Identity();
    from_canvas(0, 2) = from_canvas(1, 2) = -pad_;
    const Eigen::Matrix3d H = camera_homography(options_, frame) * from_canvas;
    cv::Mat Hcv(3, 3, CV_64F);
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) Hcv.at<double>(r, c) = H(r, c);
    }
    cv::warpPerspective(canvas, image, Hcv, size, cv::INTER_LINEAR, cv::BORDER_REFLECT_101);
  }
  if (options_.noise > 0.0) {
    cv::Mat noise(image.size(), CV_32F);
    noise_rng_.fill(noise, cv::RNG::NORMAL, 0.0, options_.noise);
    image += noise;
  }
  cv::Mat image8;
  image.convertTo(image8, CV_8U);  // rounds and saturates to 0..255
  return image8;
}

}  // namespace sinew::tools::synth
