#include "rt/whisker/detection.hpp"

#include "common/detail/field_error.hpp"
#include "rt/whisker/detail/chessboard_distance.hpp"
#include "rt/whisker/detail/ellipse_dilation.hpp"
#include "rt/whisker/detail/float_select.hpp"

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace sinew::rt {

namespace {

// The detection's fixed scales and thresholds (once WhiskerDetectionOptions fields that no tool,
// test or user set; issue 48 counts every option a user could tune). Each with the reason for its
// value; the measurements are in docs/tracker.md.
struct DetectionConstants {
  // Gaussian smoothing before the ridge contrast is read, pixels.
  double smoothing_px = 1.0;
  // Scale of the Hessian that gives the ridge direction, pixels.
  double orientation_scale_px = 1.5;
  // The ridge contrast is averaged along the ridge over ±this many pixels ...
  int contrast_averaging_px = 3;
  // ... and then smoothed by a Gaussian of this σ, pixels.
  double contrast_smoothing_px = 1.0;
  // Distance of the side samples from the ridge centre, pixels: the tracker's line_surround_px.
  int surround_px = 3;
  // A trace is a whisker only if its median contrast is at most this (per cent, in the averaged
  // map): a backlit hair is faint (shared video 1.7-4.7 %, rendered pads 1.1-3.0 %), a rod of
  // the apparatus is not (9-14 %).
  double max_contrast = 7.0;
  // The seed and follow thresholds are raised to these multiples of the contrast map's own
  // noise (its robust σ over the backlight), so that noise is neither seeded nor followed.
  double seed_noise_factor = 4.0;
  double follow_noise_factor = 2.5;
  // The smoothing polynomial is fitted to the points farther than surround_px + this from the
  // face's dark mask (nearer, a side sample falls on the face), pixels; a trace it misses by more
  // than smoothing_max_residual_px is two whiskers or a whisker and fur (shared video, frame 0:
  // whiskers <= 0.92 px, traces hopping between the dense cluster's whiskers 2.2-2.5 px).
  double smoothing_clear_px = 8.0;
  double smoothing_max_residual_px = 1.5;
  // repair_traces: extensions to the face reach at most max_extension_px and are kept only
  // within pad_extent_px of a follicle a trace reached by itself, pixels.
  double max_extension_px = 25.0;
  double pad_extent_px = 30.0;
  // Seeds lie within this distance of the face's edge, pixels.
  double pad_band_px = 10.0;
  // A trace whose points lie within this of a longer whisker over most of its length is that
  // whisker, pixels.
  double min_separation_px = 2.0;
  // At most this many whiskers are reported (the longest).
  int max_whiskers = 64;
  // The face's contrast (backlight - face level) / backlight at and above which the thresholds in
  // per cent of the backlight (seed, follow, max_contrast) hold as
  // set (the rendered pads measure 0.92, the shared video 0.99, sinew-synth's pads 0.88). Below it
  // they scale with it: a video of half the contrast has whiskers and rods of half the contrast
  // (the shared video with its contrast halved: rods of 4.5-7 %, which max_contrast's 7 % took
  // for whiskers).
  double reference_face_contrast = 0.85;
};
constexpr DetectionConstants kFixed{};

std::string field_error(const char* field, double value, const char* constraint) {
  return common::detail::field_error("whisker detection: ", field, value, constraint);
}

// Bilinear read of a float map; false outside. Always inlined: build_maps reads 2-4 of these per
// pixel for the ridge contrast and 7 more per pixel for its averaging, and as a call it was ~40 %
// of detection's time on the shared video (the same arithmetic either way).
[[gnu::always_inline]] inline bool sample(const cv::Mat& m, double x, double y, float* v) {
  if (!(x >= 0.0 && y >= 0.0 && x <= m.cols - 1.0 && y <= m.rows - 1.0)) return false;
  int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  x0 = std::min(x0, m.cols - 2);
  y0 = std::min(y0, m.rows - 2);
  const float fx = static_cast<float>(x - x0), fy = static_cast<float>(y - y0);
  const float* r0 = m.ptr<float>(y0);
  const float* r1 = m.ptr<float>(y0 + 1);
  const float top = r0[x0] + fx * (r0[x0 + 1] - r0[x0]);
  const float bottom = r1[x0] + fx * (r1[x0 + 1] - r1[x0]);
  *v = top + fy * (bottom - top);
  return true;
}

// sample() where the caller knows (x, y) lies in [0, cols − 2] × [0, rows − 2] (at most 3 px from
// a pixel kInsideMargin inside the border): the same arithmetic without the tests and clamps.
constexpr int kInsideMargin = 4;
[[gnu::always_inline]] inline float sample_inside(const cv::Mat& m, double x, double y) {
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const float fx = static_cast<float>(x - x0), fy = static_cast<float>(y - y0);
  const float* r0 = m.ptr<float>(y0);
  const float* r1 = m.ptr<float>(y0 + 1);
  const float top = r0[x0] + fx * (r0[x0 + 1] - r0[x0]);
  const float bottom = r1[x0] + fx * (r1[x0 + 1] - r1[x0]);
  return top + fy * (bottom - top);
}

// sample() at up to 3 px from pixel (x, y) of an image of the given size, inside_pixel telling
// whether (x, y) lies kInsideMargin or more inside its border.
[[gnu::always_inline]] inline bool sample_near(const cv::Mat& m, bool inside_pixel, double x,
                                               double y, float* v) {
  if (inside_pixel) {
    *v = sample_inside(m, x, y);
    return true;
  }
  return sample(m, x, y, v);
}

// The maps detection reads: smoothed image, Hessian normal, ridge contrast, darkness, distance
// from the face.
struct Maps {
  cv::Mat smooth;         // CV_32F, Gaussian(smoothing_px)
  cv::Mat nx, ny;         // CV_32F unit normal (direction of largest curvature)
  cv::Mat contrast;       // CV_32F ridge contrast, per cent
  cv::Mat near_contrast;  // the same, each side the brighter of 2 and surround_px out (or empty)
  cv::Mat dark;           // CV_8U, 255 where the heavily smoothed image is dark
  cv::Mat face;           // CV_8U, 255 on the face
  cv::Mat distance;       // CV_32F distance from the face, pixels
  double noise = 0.0;     // robust σ of the contrast map over the backlight, per cent
  double seed = 0.0, follow = 0.0;  // thresholds in force: the options' or the noise's
  double contrast_scale = 1.0;      // contrast_scale(backlight, dark level)
  // How deep inside the dark mask each pixel lies (chessboard distance to the nearest pixel off
  // it, capped at 255): the ridge maps (nx, ny, contrast, near_contrast) are built only to the
  // depths below. Empty: built over the whole frame.
  cv::Mat depth;
  // Set by a read of the ridge maps deeper than they were built: detection starts again with
  // them built over the whole frame (detect_whiskers), so the result never depends on the depth.
  mutable bool missed = false;
};

// Where the ridge maps are built. Every stage reads them off the dark mask (the noise, the seeds,
// the traces, which end on their first dark point) or a few pixels into it (a follicle is refined
// up to 5 px past that point, and a smoothed trace's extension ends there too): the final
// contrast maps are built to kReadDepth px inside the dark mask. They are the averaged maps
// smoothed by a Gaussian of σ = contrast_smoothing_px, which OpenCV's float GaussianBlur
// evaluates over ±kBlurReach px (kernel size round(8σ + 1) | 1), so the averaged maps are built
// kBlurReach px deeper; the averaging reads the raw maps within contrast_averaging_px + 1 px
// (bilinear), so those (and the normal, read at the same pixel) are built deeper still.
constexpr int kReadDepth = 10;
constexpr int kBlurReach = 4;
constexpr int kAveragedDepth = kReadDepth + kBlurReach;
constexpr int kRawDepth = kAveragedDepth + kFixed.contrast_averaging_px + 1;
static_assert(kFixed.contrast_smoothing_px == 1.0, "kBlurReach is OpenCV's radius at sigma 1");
static_assert(kRawDepth < 255, "depths are kept in bytes");

// Whether the pixels a bilinear read at (x, y) touches were built to `limit` (see kReadDepth);
// records a read that was not (Maps::missed). Reads outside the frame touch nothing.
[[gnu::always_inline]] inline bool built(const Maps& m, int limit, double x, double y) {
  const cv::Mat& d = m.depth;
  if (d.empty() || !(x >= 0.0 && y >= 0.0 && x <= d.cols - 1.0 && y <= d.rows - 1.0)) return true;
  const int x0 = std::min(static_cast<int>(x), d.cols - 2);
  const int y0 = std::min(static_cast<int>(y), d.rows - 2);
  const std::uint8_t* r0 = d.ptr<std::uint8_t>(y0);
  const std::uint8_t* r1 = d.ptr<std::uint8_t>(y0 + 1);
  if (std::max(std::max(r0[x0], r0[x0 + 1]), std::max(r1[x0], r1[x0 + 1])) <= limit) return true;
  m.missed = true;
  return false;
}

// Ridge normal at (x, y): direction of the largest eigenvalue of the Hessian there.
Eigen::Vector2d normal_at(const Maps& m, double x, double y) {
  built(m, kRawDepth, x, y);
  float a = 1.0f, b = 0.0f;
  sample(m.nx, x, y, &a);
  sample(m.ny, x, y, &b);
  // The maps hold a direction field (n and −n are the same); bilinear blending of opposite
  // neighbours is avoided by reading the nearest pixel when the blend is short.
  Eigen::Vector2d n(a, b);
  if (n.norm() < 0.5) {
    const int xi = std::clamp(static_cast<int>(std::lround(x)), 0, m.nx.cols - 1);
    const int yi = std::clamp(static_cast<int>(std::lround(y)), 0, m.nx.rows - 1);
    if (!m.depth.empty() && m.depth.at<std::uint8_t>(yi, xi) > kRawDepth) m.missed = true;
    n = Eigen::Vector2d(m.nx.at<float>(yi, xi), m.ny.at<float>(yi, xi));
  }
  return n.normalized();
}

float contrast_at(const Maps& m, const Eigen::Vector2d& p) {
  built(m, kReadDepth, p.x(), p.y());
  float v = 0.0f;
  return sample(m.contrast, p.x(), p.y(), &v) ? v : 0.0f;
}

// The contrast maximum across a ridge at q (unit normal n) within ±1.5 px in 0.25 px steps (0
// outside the frame), and its offset along n. With local_only, only a local maximum inside the
// window counts (-1e9 and offset 0 when there is none): where whiskers converge on the pad, a
// maximum at the window's edge is the flank of a darker neighbour 4-6 px away, and re-centring
// onto it walked the trace over to the neighbour. Farther out it is kept: a whisker pressed
// against a pole has its ridge there (rendered pad: 41 contact frames missed without it).
double across_maximum(const Maps& m, const cv::Mat& map, const Eigen::Vector2d& q,
                      const Eigen::Vector2d& n, bool local_only, double* offset) {
  constexpr int kReach = 6;
  float v[2 * kReach + 1];
  for (int k = -kReach; k <= kReach; ++k) {
    const Eigen::Vector2d r = q + 0.25 * k * n;
    built(m, kReadDepth, r.x(), r.y());
    if (!sample(map, r.x(), r.y(), &v[k + kReach])) v[k + kReach] = 0.0f;
  }
  double best = -1e9;
  *offset = 0.0;
  for (int i = 0; i <= 2 * kReach; ++i) {
    const bool local = i > 0 && i < 2 * kReach && v[i] >= v[i - 1] && v[i] >= v[i + 1];
    if ((local || !local_only) && v[i] > best) {
      best = v[i];
      *offset = 0.25 * (i - kReach);
    }
  }
  return best;
}

bool is_dark(const Maps& m, const Eigen::Vector2d& p) {
  const int x = static_cast<int>(std::lround(p.x())), y = static_cast<int>(std::lround(p.y()));
  if (x < 0 || y < 0 || x >= m.dark.cols || y >= m.dark.rows) return true;
  return m.dark.at<std::uint8_t>(y, x) != 0;
}

float face_distance(const Maps& m, const Eigen::Vector2d& p) {
  float v = 0.0f;
  return sample(m.distance, p.x(), p.y(), &v) ? v : 0.0f;
}

// The backlight's level (the 95th percentile of the frame smoothed by 4 px) and the face's (its
// 1st percentile).
void measure_levels(const cv::Mat& coarse, detail::FloatSelect& select, double* backlight,
                    double* dark_level) {
  auto visit = [&](auto&& f) {
    for (int y = 0; y < coarse.rows; ++y) {
      const float* row = coarse.ptr<float>(y);
      for (int x = 0; x < coarse.cols; ++x) f(row[x]);
    }
  };
  const std::size_t n = select.histogram(visit);
  *backlight = select.kth(n * 95 / 100, visit);
  *dark_level = std::min<double>(select.kth(n / 100, visit), *backlight);
}

// The unit direction (cos θ, sin θ) of the largest eigenvalue of the symmetric [[a, b], [b, c]],
// θ = atan2(2b, a − c) / 2 in (−π/2, π/2]: by the half-angle formulas from cos 2θ = (a − c)/r,
// sin 2θ = 2b/r (r = |(a − c, 2b)|), each component from the form without cancellation (the larger
// from a square root, the other as sin 2θ over twice it). Within 3.3e-16 of cos and sin of the
// half atan2 (2e7 random Hessians: 0.04 % of the components differ by one unit in the last place
// of a float), at a fraction of the cost: atan2, sin and cos were 14 % of a whole sinew-track run.
// Where 2b is ±0 (flat regions, axis-aligned ridges) the trigonometric form, whose signed zeros and
// cos(π/2) ≈ 6e-17 decide which border samples are inside the frame.
inline void largest_curvature_direction(double a, double b, double c, double* nx, double* ny) {
  const double u = a - c, v = 2.0 * b;
  if (v == 0.0) {
    const double theta = 0.5 * std::atan2(v, u);
    *nx = std::cos(theta);
    *ny = std::sin(theta);
    return;
  }
  const double r = std::sqrt(u * u + v * v);
  if (u >= 0.0) {
    *nx = std::sqrt((r + u) / (2.0 * r));  // cos θ ≥ 1/√2
    *ny = v / (2.0 * r * *nx);
  } else {
    *ny = std::copysign(std::sqrt((r - u) / (2.0 * r)), v);  // |sin θ| > 1/√2
    *nx = v / (2.0 * r * *ny);
  }
}

// The buffers a detection fills besides its maps (WhiskerDetectionWorkspace::Buffers).
struct Scratch {
  cv::Mat f, hs, dxx, dyy, dxy, coarse, labels, not_face, raw;
  detail::FloatSelect select;
  std::vector<int> hits;
  cv::Mat claimed, taken;
  cv::Mat objects, object_labels, not_objects, object_distance;
};

// Fills the maps (in m, which keeps its buffers from the last frame) and resolves the face side.
// by_depth: the ridge maps only where a stage reads them (kReadDepth); else over the whole frame.
void build_maps(const ImageView& frame, const WhiskerDetectionOptions& o, bool by_depth,
                FaceSide* side, double* backlight, double* dark_level, Maps& m, Scratch& scratch) {
  m.noise = 0.0;
  m.missed = false;
  const cv::Mat grey(frame.height, frame.width, CV_8UC1, const_cast<std::uint8_t*>(frame.data),
                     static_cast<std::size_t>(frame.stride));
  cv::Mat& f = scratch.f;
  grey.convertTo(f, CV_32F);
  cv::GaussianBlur(f, m.smooth, cv::Size(), kFixed.smoothing_px);
  cv::Mat &hs = scratch.hs, &dxx = scratch.dxx, &dyy = scratch.dyy, &dxy = scratch.dxy;
  cv::GaussianBlur(f, hs, cv::Size(), kFixed.orientation_scale_px);
  cv::Sobel(hs, dxx, CV_32F, 2, 0, 3);
  cv::Sobel(hs, dyy, CV_32F, 0, 2, 3);
  cv::Sobel(hs, dxy, CV_32F, 1, 1, 3);
  // Dark regions: heavily smoothed (whiskers vanish), below dark_threshold (higher where the
  // face stands out less: the shared video with its contrast halved had no face below 0.35 of
  // the backlight; docs/whisker_benchmark.md).
  cv::Mat& coarse = scratch.coarse;
  cv::GaussianBlur(f, coarse, cv::Size(), 4.0);
  measure_levels(coarse, scratch.select, backlight, dark_level);
  cv::compare(coarse, dark_threshold(o.dark_fraction, *backlight, *dark_level), m.dark, cv::CMP_LT);

  // The face: the dark components touching the chosen border.
  cv::Mat& labels = scratch.labels;
  const int count = cv::connectedComponents(m.dark, labels, 8, CV_32S);
  auto border_labels = [&](FaceSide s2, std::vector<int>* hits) {
    hits->assign(count, 0);
    const int w = labels.cols, h = labels.rows;
    const int n = s2 == FaceSide::kLeft || s2 == FaceSide::kRight ? h : w;
    for (int k = 0; k < n; ++k) {
      const int x = s2 == FaceSide::kLeft ? 0 : s2 == FaceSide::kRight ? w - 1 : k;
      const int y = s2 == FaceSide::kTop ? 0 : s2 == FaceSide::kBottom ? h - 1 : k;
      (*hits)[labels.at<int>(y, x)]++;
    }
    (*hits)[0] = 0;  // background
    int total = 0;
    for (int i = 1; i < count; ++i) total += (*hits)[i];
    return static_cast<double>(total) / n;
  };
  std::vector<int>& hits = scratch.hits;
  if (*side == FaceSide::kAuto) {
    double best = -1.0;
    for (FaceSide s2 : {FaceSide::kLeft, FaceSide::kRight, FaceSide::kTop, FaceSide::kBottom}) {
      const double fraction = border_labels(s2, &hits);
      if (fraction > best) {
        best = fraction;
        *side = s2;
      }
    }
  }
  border_labels(*side, &hits);
  m.face.create(f.size(), CV_8U);
  for (int y = 0; y < labels.rows; ++y) {
    const int* label = labels.ptr<int>(y);
    std::uint8_t* face = m.face.ptr<std::uint8_t>(y);
    for (int x = 0; x < labels.cols; ++x) face[x] = hits[label[x]] > 0 ? 255 : 0;
  }
  cv::Mat& not_face = scratch.not_face;
  cv::bitwise_not(m.face, not_face);
  cv::distanceTransform(not_face, m.distance, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  m.nx.create(f.size(), CV_32F);
  m.ny.create(f.size(), CV_32F);
  m.contrast.create(f.size(), CV_32F);
  if (by_depth) {
    detail::chessboard_distance(m.dark, m.depth);
  } else {
    m.depth.release();
  }
  const bool near = o.near_follow_px > 0.0;
  // The second map is read only near the face: computed there (and as far out as its averaging
  // and smoothing reach), zero elsewhere.
  const float near_band =
      static_cast<float>(o.near_follow_px + kFixed.surround_px + kFixed.contrast_averaging_px +
                         3.0 * kFixed.contrast_smoothing_px);
  if (near) {
    m.near_contrast.create(f.size(), CV_32F);
  } else {
    m.near_contrast.release();
  }
  const double s = kFixed.surround_px;
  static_assert(kFixed.surround_px + 1 <= kInsideMargin, "sample_near reaches 3 px");
  for (int y = 0; y < f.rows; ++y) {
    const bool inside_row = y >= kInsideMargin && y < f.rows - kInsideMargin;
    const std::uint8_t* depth = by_depth ? m.depth.ptr<std::uint8_t>(y) : nullptr;
    for (int x = 0; x < f.cols; ++x) {
      if (depth && depth[x] > kRawDepth) {
        // Deep inside a dark region, where nothing reads the maps (built()): fixed values.
        m.nx.at<float>(y, x) = 1.0f;
        m.ny.at<float>(y, x) = 0.0f;
        m.contrast.at<float>(y, x) = 0.0f;
        if (near) m.near_contrast.at<float>(y, x) = 0.0f;
        continue;
      }
      const bool inside = inside_row && x >= kInsideMargin && x < f.cols - kInsideMargin;
      // Sobel's second-derivative kernels carry a factor 4 (dxx, dyy) and 4 (dxy) alike.
      const double a = dxx.at<float>(y, x), c = dyy.at<float>(y, x), b = dxy.at<float>(y, x);
      double nxv, nyv;
      largest_curvature_direction(a, b, c, &nxv, &nyv);
      m.nx.at<float>(y, x) = static_cast<float>(nxv);
      m.ny.at<float>(y, x) = static_cast<float>(nyv);
      float left, right, centre = m.smooth.at<float>(y, x);
      float value = 0.0f, near_value = 0.0f;
      if (sample_near(m.smooth, inside, x - s * nxv, y - s * nyv, &left) &&
          sample_near(m.smooth, inside, x + s * nxv, y + s * nyv, &right)) {
        const float lo = std::min(left, right), hi = std::max(left, right);
        value = 100.0f * (lo - centre) / std::max(hi, 1.0f);
        float l2 = left, r2 = right;
        if (near && m.distance.at<float>(y, x) < near_band &&
            sample_near(m.smooth, inside, x - 2.0 * nxv, y - 2.0 * nyv, &l2) &&
            sample_near(m.smooth, inside, x + 2.0 * nxv, y + 2.0 * nyv, &r2)) {
          l2 = std::max(l2, left);
          r2 = std::max(r2, right);
          near_value = 100.0f * (std::min(l2, r2) - centre) / std::max(std::max(l2, r2), 1.0f);
        }
      }
      m.contrast.at<float>(y, x) = value;
      if (near) m.near_contrast.at<float>(y, x) = near_value;
    }
  }

  // Averaged along the ridge (its Hessian tangent, ±contrast_averaging_px): along a whisker the
  // contrast adds up and the noise does not, so a faint tip stays above the noise threshold for
  // longer; across, the peak stays as sharp as it was.
  for (cv::Mat* map : {&m.contrast, &m.near_contrast}) {
    if (map->empty()) continue;
    const bool banded = map == &m.near_contrast;
    if (kFixed.contrast_averaging_px > 0) {
      cv::Mat& raw = scratch.raw;
      map->copyTo(raw);
      constexpr int reach = kFixed.contrast_averaging_px;
      static_assert(reach + 1 <= kInsideMargin, "sample_near reaches 3 px");
      for (int y = 0; y < f.rows; ++y) {
        const bool inside_row = y >= kInsideMargin && y < f.rows - kInsideMargin;
        const std::uint8_t* depth = by_depth ? m.depth.ptr<std::uint8_t>(y) : nullptr;
        for (int x = 0; x < f.cols; ++x) {
          if (banded && !(m.distance.at<float>(y, x) < near_band)) continue;
          if (depth && depth[x] > kAveragedDepth) continue;  // never read: keeps the raw value
          const bool inside = inside_row && x >= kInsideMargin && x < f.cols - kInsideMargin;
          const double tx = -m.ny.at<float>(y, x), ty = m.nx.at<float>(y, x);
          double sum = 0.0;
          int samples = 0;
          if (inside) {
            // Every sample is inside: read them all first (independent), then add them in the
            // same order as below.
            float v[2 * reach + 1];
            for (int k = -reach; k <= reach; ++k) {
              v[k + reach] = sample_inside(raw, x + k * tx, y + k * ty);
            }
            for (int k = 0; k <= 2 * reach; ++k) sum += v[k];
            samples = 2 * reach + 1;
          } else {
            for (int k = -reach; k <= reach; ++k) {
              float v;
              if (sample(raw, x + k * tx, y + k * ty, &v)) {
                sum += v;
                ++samples;
              }
            }
          }
          map->at<float>(y, x) = static_cast<float>(sum / std::max(samples, 1));
        }
      }
    }
    if (kFixed.contrast_smoothing_px > 0.0) {
      cv::GaussianBlur(*map, *map, cv::Size(), kFixed.contrast_smoothing_px);
    }
  }

  // The contrast map's noise: most backlight pixels are on no ridge, so the median |contrast|
  // there is the noise's (× 1.4826 for σ).
  auto background = [&](auto&& visit) {
    for (int y = 0; y < f.rows; ++y) {
      const std::uint8_t* dark = m.dark.ptr<std::uint8_t>(y);
      const float* contrast = m.contrast.ptr<float>(y);
      for (int x = 0; x < f.cols; ++x) {
        if (!dark[x]) visit(std::abs(contrast[x]));
      }
    }
  };
  if (const std::size_t n = scratch.select.histogram(background); n > 0) {
    m.noise = 1.4826 * scratch.select.kth(n / 2, background);
  }
  m.contrast_scale = contrast_scale(*backlight, *dark_level);
  m.seed = std::max(o.seed_contrast * m.contrast_scale, kFixed.seed_noise_factor * m.noise);
  m.follow = std::max(o.follow_contrast * m.contrast_scale, kFixed.follow_noise_factor * m.noise);
}

struct Trace {
  std::vector<Eigen::Vector2d> points;  // in tracing order
  std::vector<float> contrast;          // at each point (re-centred), per cent
  bool ended_dark = false;              // ran into a dark region (not a free tip)
};

// Steps below follow_contrast bridged on the step from p to q (see max_gap_towards_face_px).
int gap_limit(const Maps& m, const WhiskerDetectionOptions& o, const Eigen::Vector2d& p,
              const Eigen::Vector2d& q) {
  const double dq = face_distance(m, q);
  const bool towards_face = dq < face_distance(m, p) - 0.3;
  return towards_face && dq >= kFixed.surround_px + 1.0 ? o.max_gap_towards_face_px : o.max_gap_px;
}

// Follows a ridge from p along direction t (unit), re-centring each 1 px step on the contrast
// maximum across the ridge. Stops after max_gap_px steps below follow_contrast (gap_limit; the
// trace keeps the points up to the last strong one), at the image border, or on entering a dark
// region (the face, whose first point it keeps).
Trace follow(const Maps& m, const WhiskerDetectionOptions& o, Eigen::Vector2d p,
             Eigen::Vector2d t) {
  Trace trace;
  trace.points.push_back(p);
  trace.contrast.push_back(static_cast<float>(contrast_at(m, p)));
  int gap = 0;
  std::size_t last_strong = 0;
  const int max_steps = 4 * (m.contrast.cols + m.contrast.rows);
  for (int step = 0; step < max_steps; ++step) {
    Eigen::Vector2d q = p + t;
    if (q.x() < 1.0 || q.y() < 1.0 || q.x() > m.contrast.cols - 2.0 ||
        q.y() > m.contrast.rows - 2.0) {
      break;
    }
    if (is_dark(m, q)) {
      // Entering the face (or another dark object): the first dark point ends the trace.
      trace.points.push_back(q);
      trace.contrast.push_back(0.0f);
      last_strong = trace.points.size() - 1;
      trace.ended_dark = true;
      break;
    }
    Eigen::Vector2d n(-t.y(), t.x());
    // Re-centre: the contrast maximum across the ridge within ±1.5 px.
    double best_offset = 0.0;
    const bool near_face = face_distance(m, q) < o.near_follow_px;
    double best = across_maximum(m, m.contrast, q, n, near_face, &best_offset);
    if (best < m.follow && !m.near_contrast.empty() && near_face) {
      // Beside a neighbour 3-4 px away (whiskers converging on the pad) the side sample falls on
      // its shoulder and the contrast reads ~0: read the gap before it instead.
      double near_offset = 0.0;
      const double best_near = across_maximum(m, m.near_contrast, q, n, true, &near_offset);
      if (best_near >= m.follow) {
        best = best_near;
        best_offset = near_offset;
      }
    }
    if (best >= m.follow) {
      q += best_offset * n;
      gap = 0;
    } else if (++gap > gap_limit(m, o, p, q)) {
      break;
    }
    // The new direction: the ridge's own (Hessian) tangent, oriented along the trace, blended
    // with the chord over the last few points so noise does not turn it.
    const Eigen::Vector2d nr = normal_at(m, q.x(), q.y());
    Eigen::Vector2d tr(-nr.y(), nr.x());
    if (tr.dot(t) < 0.0) tr = -tr;
    const std::size_t back = std::min<std::size_t>(trace.points.size(), 8);
    Eigen::Vector2d chord = q - trace.points[trace.points.size() - back];
    chord = chord.norm() > 1e-9 ? Eigen::Vector2d(chord.normalized()) : t;
    Eigen::Vector2d t_new = (0.3 * tr + 0.7 * chord);
    // A turn of more than ~25° in one pixel is not a whisker's (noise or a crossing): keep going.
    if (t_new.norm() < 1e-9 || t_new.normalized().dot(t) < 0.9) t_new = t;
    t = t_new.normalized();
    p = q;
    trace.points.push_back(p);
    trace.contrast.push_back(static_cast<float>(std::max(best, 0.0)));
    if (gap == 0) last_strong = trace.points.size() - 1;
    // A whisker does not turn by more than max_turn_deg over 12 px: a trace that does has left it
    // (noise at a faint tip, a neighbour where whiskers converge or cross).
    const std::size_t np = trace.points.size();
    if (np > 24) {
      const Eigen::Vector2d recent = trace.points[np - 1] - trace.points[np - 13];
      const Eigen::Vector2d before = trace.points[np - 13] - trace.points[np - 25];
      if (recent.normalized().dot(before.normalized()) < std::cos(o.max_turn_deg * M_PI / 180.0)) {
        last_strong = std::min(last_strong, np - 13);
        break;
      }
    }
  }
  trace.points.resize(last_strong + 1);
  trace.contrast.resize(trace.points.size());
  // The far end: each point was re-centred on the best of 13 contrasts across the ridge, so noise
  // beyond a faint tip passes the threshold now and then; the tip is the last point whose
  // contrast, averaged over ±4 points, still does (a dark end keeps its face point).
  if (!trace.ended_dark) {
    constexpr int kHalf = 4;
    const int np = static_cast<int>(trace.points.size());
    int tip = np - 1;
    while (tip > 0) {
      double sum = 0.0;
      int count = 0;
      for (int j = std::max(0, tip - kHalf); j <= std::min(np - 1, tip + kHalf); ++j) {
        sum += trace.contrast[j];
        ++count;
      }
      if (sum / count >= m.follow) break;
      --tip;
    }
    trace.points.resize(tip + 1);
  }
  return trace;
}

float median_contrast(const Maps& m, const std::vector<Eigen::Vector2d>& points) {
  std::vector<float> contrasts;
  for (const auto& p : points) contrasts.push_back(contrast_at(m, p));
  if (contrasts.empty()) return 0.0f;
  std::nth_element(contrasts.begin(), contrasts.begin() + contrasts.size() / 2, contrasts.end());
  return contrasts[contrasts.size() / 2];
}

// Moves the last point of a trace that ended in the face to the face's edge: the steepest fall of
// the lightly smoothed image along the trace's last direction, within 5 px of it.
void refine_follicle(const Maps& m, std::vector<Eigen::Vector2d>* points) {
  const Eigen::Vector2d end = points->back();
  const Eigen::Vector2d dir = (end - (*points)[points->size() - 2]).normalized();
  double best = 0.0, best_s = 0.0;
  for (int k = -20; k <= 20; ++k) {
    const double s = 0.25 * k;
    float a = 0.0f, b = 0.0f;
    const Eigen::Vector2d p = end + s * dir;
    if (!sample(m.smooth, p.x() - 0.5 * dir.x(), p.y() - 0.5 * dir.y(), &a) ||
        !sample(m.smooth, p.x() + 0.5 * dir.x(), p.y() + 0.5 * dir.y(), &b)) {
      continue;
    }
    if (a - b > best) {
      best = a - b;
      best_s = s;
    }
  }
  // Points past the edge are dropped; the edge becomes the last point.
  const Eigen::Vector2d edge = end + best_s * dir;
  while (points->size() > 1 && ((*points)[points->size() - 2] - edge).dot(dir) >= 0.0) {
    points->pop_back();
  }
  points->back() = edge;
}

// Median contrast of the last 10 points of a trace (its far end).
float end_contrast(const Maps& m, const std::vector<Eigen::Vector2d>& points) {
  const std::size_t k = std::min<std::size_t>(points.size(), 10);
  return median_contrast(m, std::vector<Eigen::Vector2d>(points.end() - k, points.end()));
}

// The largest turn of a trace (points ~1 px apart) between the chords over 12 points before and
// after any of its points, degrees.
double largest_turn_deg(const std::vector<Eigen::Vector2d>& pts) {
  double worst = 1.0;  // cosine
  for (std::size_t i = 12; i + 12 < pts.size(); ++i) {
    const Eigen::Vector2d a = pts[i] - pts[i - 12], b = pts[i + 12] - pts[i];
    if (a.norm() < 1e-9 || b.norm() < 1e-9) continue;
    worst = std::min(worst, a.normalized().dot(b.normalized()));
  }
  return std::acos(std::clamp(worst, -1.0, 1.0)) * 180.0 / M_PI;
}

double polyline_length(const std::vector<Eigen::Vector2d>& pts) {
  double length = 0.0;
  for (std::size_t i = 1; i < pts.size(); ++i) length += (pts[i] - pts[i - 1]).norm();
  return length;
}

// A least-squares polynomial of `degree` through a whisker's trace, x and y each in the
// normalised arc length, fitted to the points at least `clear_px` from the face: nearer the face a
// side sample of the ridge measure falls on it and pulls the trace away from it (rendered pad,
// 5-grey-level whisker: 2.1 px sideways at the follicle, fading over its first 8 px). The fit is
// extended from its first point along its tangent to the face's edge (the steepest fall of the
// lightly smoothed image, refine_follicle), and the result resampled at 1 px. A trace with too
// few points beyond the face keeps its own points.
//
// A trace the fit misses by more than max_residual_px is not one whisker: where whiskers converge
// towards the pad or cross, a trace hops from one to the next (shared video, frame 0: 2.2-2.5 px
// off a cubic). It is cut at its worst point, on the side with fewer points (a hop near the face
// leaves the outer part; one at the tip, the part at the face), and fitted again, while at least
// min_length_px remain. A trace that does not reach the face (cut there, or it ended on a
// converging neighbour's ridge) is extended along its tangent to the face when the face lies
// within max_extension_px and the extension stays on a ridge (the neighbour's: they share it
// there): it is reported from where it meets the face. Gives nothing when no such stretch is left.
std::vector<Eigen::Vector2d> smooth_trace(const Maps& m, const std::vector<Eigen::Vector2d>& points,
                                          bool reaches_face, bool may_extend,
                                          const WhiskerDetectionOptions& o, bool* extended_out) {
  *extended_out = false;
  const double clear_px = kFixed.surround_px + kFixed.smoothing_clear_px;
  std::vector<double> s(points.size(), 0.0);
  for (std::size_t i = 1; i < points.size(); ++i) {
    s[i] = s[i - 1] + (points[i] - points[i - 1]).norm();
  }
  std::size_t first = 0;
  while (first < points.size() && face_distance(m, points[first]) < clear_px) ++first;
  std::size_t last = points.size() - 1;
  if (first > last) return points;
  bool cut_at_face = false;
  int degree = 0;
  double s0 = 0.0, span = 0.0;
  Eigen::MatrixXd c;
  for (;;) {
    const std::size_t n = last - first + 1;
    // A short stretch is fitted by a lower degree (one per 15 points): a cubic through 30 noisy
    // points bends at its ends.
    degree = std::min(o.smoothing_degree, static_cast<int>(n / 15));
    s0 = s[first];
    span = s[last] - s0;
    if (degree < 1 || !(span > 1.0)) {
      if (cut_at_face || last + 1 < points.size()) return {};
      return points;
    }
    Eigen::MatrixXd V(static_cast<Eigen::Index>(n), degree + 1);
    Eigen::MatrixXd P(static_cast<Eigen::Index>(n), 2);
    for (std::size_t i = 0; i < n; ++i) {
      const double u = (s[first + i] - s0) / span;
      double power = 1.0;
      for (int k = 0; k <= degree; ++k, power *= u) V(static_cast<Eigen::Index>(i), k) = power;
      P.row(static_cast<Eigen::Index>(i)) = points[first + i].transpose();
    }
    c = V.colPivHouseholderQr().solve(P);
    Eigen::Index worst = 0;
    if ((V * c - P).rowwise().norm().maxCoeff(&worst) <= kFixed.smoothing_max_residual_px) break;
    // Cut 5 px beyond the worst point, on the side with fewer points.
    const std::size_t k = first + static_cast<std::size_t>(worst);
    if (!o.repair_traces) return {};
    if (k - first > last - k) {
      last = k > first + 5 ? k - 5 : first;
    } else {
      first = k + 5;
      cut_at_face = true;
    }
    if (first >= last || s[last] - s[first] < o.min_length_px) return {};
  }
  auto at = [&](double u) {
    Eigen::Vector2d p = Eigen::Vector2d::Zero();
    for (int k = degree; k >= 0; --k) p = p * u + c.row(k).transpose();
    return p;
  };
  auto tangent_at = [&](double u) {
    Eigen::Vector2d d = Eigen::Vector2d::Zero();
    for (int k = degree; k >= 1; --k) d = d * u + k * c.row(k).transpose();
    return d;
  };
  const Eigen::Vector2d start = at(0.0);
  Eigen::Vector2d t = tangent_at(0.0);
  if (!(t.norm() > 0.0)) {
    if (cut_at_face || last + 1 < points.size()) return {};
    return points;
  }
  t.normalize();
  // Back to the face along the tangent: into the dark mask (which lies ~2 px inside the edge),
  // at most as far as the raw trace went, or, for a trace that did not reach the face,
  // max_extension_px.
  const bool extended = may_extend && (cut_at_face || !reaches_face);
  *extended_out = extended;
  std::vector<Eigen::Vector2d> out;
  const double reach = extended ? s0 + kFixed.max_extension_px : s0 + 4.0;
  double back = 0.0;
  while (back < reach && !is_dark(m, start - back * t)) back += 0.5;
  if (extended) {
    if (!is_dark(m, start - back * t)) return {};
    // The extension beyond the trace's own points lies on a ridge where the measure can see one
    // (farther than the side samples from the face).
    int seen = 0, on = 0;
    for (double b = 1.0; b < back; b += 1.0) {
      const Eigen::Vector2d q = start - b * t;
      if (face_distance(m, q) < kFixed.surround_px + 1.0) continue;
      ++seen;
      // Where whiskers converge a side sample of the ridge measure falls on the neighbour and the
      // measure reads ~0; the band they form is still darker than the backlight beside it.
      float centre = 0.0f, left = 0.0f, right = 0.0f;
      const Eigen::Vector2d side(-t.y() * 5.0, t.x() * 5.0);
      const bool band = sample(m.smooth, q.x(), q.y(), &centre) &&
                        sample(m.smooth, q.x() + side.x(), q.y() + side.y(), &left) &&
                        sample(m.smooth, q.x() - side.x(), q.y() - side.y(), &right) &&
                        centre < 0.5f * (left + right) - 0.01f * std::max(left, right);
      on += contrast_at(m, q) >= m.follow || band;
    }
    if (seen > 0 && on < 0.6 * seen) return {};
  }
  for (double b = 0.0; b < back + 0.5; b += 1.0) out.push_back(start - b * t);
  if (out.size() >= 2) refine_follicle(m, &out);  // the face at the back
  std::reverse(out.begin(), out.end());
  out.pop_back();  // start, the polynomial's first sample below
  // The trace itself reached the face (ended_dark): its follicle and the extension's agree
  // within the trace's noise; one that does not is a trace whose start turns (a hop between
  // converging whiskers).
  if (!extended && (out.empty() || (out.front() - points.front()).norm() > 4.0)) return points;
  if (out.empty()) return {};
  const int samples = std::max(2, static_cast<int>(std::ceil(span)));
  for (int k = 0; k <= samples; ++k) out.push_back(at(static_cast<double>(k) / samples));
  return out;
}

}  // namespace

const char* to_string(FaceSide side) {
  switch (side) {
    case FaceSide::kAuto:
      return "auto";
    case FaceSide::kLeft:
      return "left";
    case FaceSide::kRight:
      return "right";
    case FaceSide::kTop:
      return "top";
    case FaceSide::kBottom:
      return "bottom";
  }
  return "unknown";
}

std::optional<FaceSide> face_side_from_string(const std::string& name) {
  for (FaceSide f :
       {FaceSide::kAuto, FaceSide::kLeft, FaceSide::kRight, FaceSide::kTop, FaceSide::kBottom}) {
    if (name == to_string(f)) return f;
  }
  return std::nullopt;
}

double contrast_scale(double backlight, double dark_level) {
  if (!(backlight > 0.0)) return 1.0;
  const double face_contrast = (backlight - dark_level) / backlight;
  return std::clamp(face_contrast / kFixed.reference_face_contrast, 0.05, 1.0);
}

double dark_threshold(double fraction, double backlight, double dark_level) {
  // A face that stands out as usual: the fraction of the backlight the defaults were set with.
  if (contrast_scale(backlight, dark_level) >= 1.0) return fraction * backlight;
  // A lit face (a video of low contrast): the fraction of the way from the face's level up to
  // the backlight, which a change of contrast maps onto itself. (Scaling the fraction of the
  // backlight by contrast_scale instead left the pole of the shared video at half contrast, at
  // 0.60-0.66 of the backlight, above the threshold: 31 whisker-frames were fitted onto it.)
  return dark_level + fraction * (backlight - dark_level);
}

std::optional<std::string> WhiskerDetectionOptions::validate() const {
  if (!(seed_contrast > 0.0)) return field_error("seed_contrast", seed_contrast, "must be > 0");
  if (!(follow_contrast > 0.0)) {
    return field_error("follow_contrast", follow_contrast, "must be > 0");
  }
  if (!(max_turn_deg > 0.0 && max_turn_deg < 180.0))
    return field_error("max_turn_deg", max_turn_deg, "must be in (0, 180)");
  if (max_gap_px < 0) return field_error("max_gap_px", max_gap_px, "must be >= 0");
  if (max_gap_towards_face_px < max_gap_px) {
    return field_error("max_gap_towards_face_px", max_gap_towards_face_px, "must be >= max_gap_px");
  }
  if (!(min_length_px >= 0.0)) return field_error("min_length_px", min_length_px, "must be >= 0");
  if (!(dark_fraction > 0.0 && dark_fraction < 1.0)) {
    return field_error("dark_fraction", dark_fraction, "must be in (0, 1)");
  }
  if (!(object_fraction > 0.0 && object_fraction < 1.0))
    return field_error("object_fraction", object_fraction, "must be in (0, 1)");
  if (smoothing_degree < 0 || smoothing_degree > 6) {
    return field_error("smoothing_degree", smoothing_degree, "must be in [0, 6]");
  }
  if (!(near_follow_px >= 0.0))
    return field_error("near_follow_px", near_follow_px, "must be >= 0");
  if (!(min_clear_length_px >= 0.0)) {
    return field_error("min_clear_length_px", min_clear_length_px, "must be >= 0");
  }
  return std::nullopt;
}

namespace {

// A ridge centre a trace starts from.
struct Seed {
  Eigen::Vector2d p;
  float contrast;
};

// A traced whisker before the pad and overlap tests.
struct Candidate {
  DetectedWhisker whisker;
  bool extended = false;  // its follicle is an extension along its tangent (smooth_trace)
};

std::vector<Seed> find_seeds(const Maps& m) {
  // Seeds: ridge centres (contrast maxima across the ridge) outside the dark regions. Not only
  // near the face: a whisker that leaves the face behind a neighbour shows its own ridge only
  // farther out, and is traced back to the face from there.
  std::vector<Seed> seeds;
  for (int y = 1; y < m.contrast.rows - 1; ++y) {
    for (int x = 1; x < m.contrast.cols - 1; ++x) {
      const float d = m.distance.at<float>(y, x);
      const float c = m.contrast.at<float>(y, x);
      if (d < 2.0f || c < m.seed || m.dark.at<std::uint8_t>(y, x)) {
        continue;
      }
      const Eigen::Vector2d p(x, y), n = normal_at(m, x, y);
      if (contrast_at(m, p + n) > c || contrast_at(m, p - n) > c) continue;
      seeds.push_back({p, c});
    }
  }
  std::sort(seeds.begin(), seeds.end(),
            [](const Seed& a, const Seed& b) { return a.contrast > b.contrast; });
  return seeds;
}

// Traces every seed (strongest first) that no earlier trace claimed; the traces that start at the
// face and leave it, light enough and long enough, are the candidates (the others go to
// result.rejected when o.keep_rejected).
// The length of a trace farther than surround_px + smoothing_clear_px from the face (where its
// ridge measure does not read the face), and its farthest distance from the face.
double clear_length(const Maps& m, const std::vector<Eigen::Vector2d>& points, float* farthest) {
  const double clear_px = kFixed.surround_px + kFixed.smoothing_clear_px;
  double beyond = 0.0;
  bool previous_clear = false;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const float d = face_distance(m, points[i]);
    *farthest = std::max(*farthest, d);
    const bool clear = d >= clear_px;
    if (clear && previous_clear) beyond += (points[i] - points[i - 1]).norm();
    previous_clear = clear;
  }
  return beyond;
}

// The pad's middle: the coordinate-wise median of the follicles that traces reached by
// themselves (not extended); nullopt when there are none.
std::optional<Eigen::Vector2d> pad_centre_of(const std::vector<Candidate>& found) {
  std::vector<double> xs, ys;
  for (const Candidate& c : found) {
    if (c.extended) continue;
    xs.push_back(c.whisker.follicle.x());
    ys.push_back(c.whisker.follicle.y());
  }
  if (xs.empty()) return std::nullopt;
  std::nth_element(xs.begin(), xs.begin() + xs.size() / 2, xs.end());
  std::nth_element(ys.begin(), ys.begin() + ys.size() / 2, ys.end());
  return Eigen::Vector2d(xs[xs.size() / 2], ys[ys.size() / 2]);
}

std::vector<Candidate> trace_seeds(const Maps& m, const WhiskerDetectionOptions& o,
                                   const std::vector<Seed>& seeds, cv::Mat& claimed,
                                   WhiskerDetection& result) {
  // Trace each seed not already on a traced whisker both ways along its ridge; the end nearer the
  // face is the follicle.
  claimed.create(m.contrast.size(), CV_8U);
  claimed.setTo(0);
  auto claim = [&](const std::vector<Eigen::Vector2d>& points) {
    for (const auto& p : points) {
      cv::circle(claimed, cv::Point(int(std::lround(p.x())), int(std::lround(p.y()))), 1, 255, -1);
    }
  };
  auto reject = [&](const std::vector<Eigen::Vector2d>& points, const char* reason) {
    if (o.keep_rejected) result.rejected.push_back({points, reason});
  };
  std::vector<Candidate> found;
  // A whisker starts at the face and leaves it; a thin structure of the apparatus, far darker
  // than a backlit hair, is not one.
  auto consider = [&](std::vector<Eigen::Vector2d> points, bool extended) {
    DetectedWhisker c;
    c.points = std::move(points);
    c.follicle = c.points.front();
    c.length_px = polyline_length(c.points);
    c.contrast_percent = median_contrast(m, c.points);
    // A whisker leaves the face: it reaches pad_band_px from it, and (min_clear_length_px; 15 px
    // is the shortest stretch smooth_trace fits a line to: a shorter one kept its raw points,
    // unchecked) runs on beyond the band where its ridge measure reads the face.
    float farthest = 0.0f;
    const double beyond = clear_length(m, c.points, &farthest);
    // The mask lies ~2 px inside the edge the follicle was refined to.
    if (face_distance(m, c.follicle) > 4.0) {
      reject(c.points, "not at the face");
    } else if (farthest < kFixed.pad_band_px ||
               (o.smoothing_degree > 0 && beyond < o.min_clear_length_px)) {
      reject(c.points, "does not leave the face");
    } else if (largest_turn_deg(c.points) > o.max_turn_deg) {
      // follow() holds each way from the seed to max_turn_deg; across the seed nothing did, and a
      // trace too short for smooth_trace's fit keeps its raw points (shared video, frame 39: a
      // trace from a whisker's middle that turned back along the cheek, 75 degrees).
      reject(c.points, "not smooth");
    } else if (c.contrast_percent > kFixed.max_contrast * m.contrast_scale) {
      reject(c.points, "too dark");
    } else if (c.length_px < o.min_length_px) {
      reject(c.points, "too short");
    } else {
      found.push_back({std::move(c), extended});
    }
  };
  // b ends at the face, a at the tip.
  auto take = [&](Trace& a, Trace& b, bool may_extend) {
    // The trace stopped at the first point of the dark mask, which its heavy smoothing puts ~2 px
    // inside the face: the follicle is where the intensity falls fastest along the whisker there
    // (the face's edge).
    if (b.ended_dark && b.points.size() >= 2) refine_follicle(m, &b.points);
    DetectedWhisker w;
    for (std::size_t i = b.points.size(); i-- > 1;) w.points.push_back(b.points[i]);
    w.points.insert(w.points.end(), a.points.begin(), a.points.end());
    if (o.smoothing_degree == 0) {
      claim(w.points);
      consider(w.points, false);
      return;
    }
    // The fit is to the ridge centres the trace measured: a step bridging a gap went straight on
    // from where the ridge was last seen, and is not a measurement of it. (refine_follicle only
    // drops or moves b's last points, so t.contrast[i] still belongs to t.points[i]; the moved
    // last point, the follicle, is kept.)
    std::vector<Eigen::Vector2d> measured;
    auto keep_measured = [&](const Trace& t, std::size_t i) {
      if (i == 0 || (t.ended_dark && i + 1 == t.points.size()) || t.contrast[i] >= m.follow) {
        measured.push_back(t.points[i]);
      }
    };
    for (std::size_t i = b.points.size(); i-- > 1;) keep_measured(b, i);
    for (std::size_t i = 0; i < a.points.size(); ++i) keep_measured(a, i);
    bool extended = false;
    std::vector<Eigen::Vector2d> smooth =
        smooth_trace(m, measured, b.ended_dark, may_extend, o, &extended);
    if (o.repair_traces && !a.ended_dark && !b.ended_dark) {
      // Neither end reached the face, and the nearer one need not be the follicle (a tip that
      // ends beside the cheek): both are candidates, the pad decides (below).
      bool reversed_extended = false;
      std::vector<Eigen::Vector2d> reversed =
          smooth_trace(m, std::vector<Eigen::Vector2d>(measured.rbegin(), measured.rend()), false,
                       may_extend, o, &reversed_extended);
      if (reversed.size() >= 2) {
        if (smooth.size() >= 2)
          consider(reversed, reversed_extended);
        else
          smooth.swap(reversed), extended = reversed_extended;
      }
    }
    if (smooth.size() < 2 && !o.repair_traces) claim(w.points);
    if (smooth.size() < 2) {
      // Repairing, only the stretch around the seed is claimed: other seeds of the whiskers
      // this trace hopped between are traced on their own.
      const std::size_t at = b.points.size() - 1;
      claim({w.points.begin() + static_cast<std::ptrdiff_t>(at - std::min<std::size_t>(at, 10)),
             w.points.begin() + static_cast<std::ptrdiff_t>(std::min(w.points.size(), at + 11))});
      reject(w.points, "not smooth");
      return;
    }
    claim(w.points);
    consider(std::move(smooth), extended);
  };

  std::vector<std::pair<Trace, Trace>> deferred;
  for (const Seed& seed : seeds) {
    const int sx = static_cast<int>(seed.p.x()), sy = static_cast<int>(seed.p.y());
    if (claimed.at<std::uint8_t>(sy, sx)) continue;
    const Eigen::Vector2d n = normal_at(m, seed.p.x(), seed.p.y());
    const Eigen::Vector2d t(-n.y(), n.x());
    Trace a = follow(m, o, seed.p, t);
    Trace b = follow(m, o, seed.p, -t);
    // The follicle is the end at the face; when both ends reach a dark region (a tip over the
    // cheek's shadow), the darker one: a whisker tapers, its contrast falls towards the tip.
    const float da = face_distance(m, a.points.back()), db = face_distance(m, b.points.back());
    if (da <= 2.0f && db <= 2.0f) {
      if (end_contrast(m, a.points) > end_contrast(m, b.points)) std::swap(a, b);
    } else if (da < db) {
      std::swap(a, b);
    }
    // Both ends near the face: a whisker whose tip lies over a dark part of the face (the cheek)
    // while its follicle end stops short of the pad, where it runs among its neighbours. Which end
    // is the follicle is decided once the pad is known.
    if (o.orient_by_pad && std::max(da, db) <= 2.0 * kFixed.pad_band_px) {
      claim(a.points);
      claim(b.points);
      deferred.emplace_back(std::move(a), std::move(b));
      continue;
    }
    take(a, b, o.repair_traces);
  }
  // The pad: the middle (coordinate-wise median) of the follicles the other traces reached by
  // themselves. A deferred trace's follicle is its end nearer to it; when that end is not at the
  // face it is extended along its tangent to the face (on a ridge or a dark band; drop_off_pad
  // keeps it only on the pad).
  const std::optional<Eigen::Vector2d> pad_centre = pad_centre_of(found);
  for (auto& [a, b] : deferred) {
    if (pad_centre &&
        (a.points.back() - *pad_centre).norm() < (b.points.back() - *pad_centre).norm()) {
      std::swap(a, b);
    }
    take(a, b, true);
  }
  return found;
}

void drop_off_pad(std::vector<Candidate>& found, const WhiskerDetectionOptions& o,
                  WhiskerDetection& result) {
  // A trace extended to the face names a follicle the image did not show: it is kept only on the
  // pad, within pad_extent_px of a follicle a trace reached by itself (a tip that ends beside the
  // cheek, extended, would name one there).
  std::vector<Eigen::Vector2d> seen_follicles;
  for (const Candidate& c : found) {
    if (!c.extended) seen_follicles.push_back(c.whisker.follicle);
  }
  found.erase(std::remove_if(found.begin(), found.end(),
                             [&](const Candidate& c) {
                               if (!c.extended) return false;
                               for (const auto& f : seen_follicles) {
                                 if ((f - c.whisker.follicle).norm() <= kFixed.pad_extent_px) {
                                   return false;
                                 }
                               }
                               if (o.keep_rejected) {
                                 result.rejected.push_back({c.whisker.points, "off the pad"});
                               }
                               return true;
                             }),
              found.end());
}

void accept_longest(std::vector<Candidate>& found, const Maps& m, const WhiskerDetectionOptions& o,
                    cv::Mat& taken, WhiskerDetection& result) {
  // The longest first; a trace running along an accepted one over most of its length is it.
  std::sort(found.begin(), found.end(), [](const Candidate& a, const Candidate& b) {
    return a.whisker.length_px > b.whisker.length_px;
  });
  taken.create(m.contrast.size(), CV_8U);
  taken.setTo(0);
  const int radius = std::max(1, static_cast<int>(std::lround(kFixed.min_separation_px)));
  for (auto& candidate : found) {
    DetectedWhisker& w = candidate.whisker;
    if (static_cast<int>(result.whiskers.size()) >= kFixed.max_whiskers) break;
    int on = 0;
    for (const auto& p : w.points) {
      on += taken.at<std::uint8_t>(int(std::lround(p.y())), int(std::lround(p.x()))) != 0;
    }
    if (on > 0.5 * static_cast<double>(w.points.size())) {
      if (o.keep_rejected) result.rejected.push_back({w.points, "runs along a longer whisker"});
      continue;
    }
    for (std::size_t i = 1; i < w.points.size(); ++i) {
      cv::line(taken, cv::Point2d(w.points[i - 1].x(), w.points[i - 1].y()),
               cv::Point2d(w.points[i].x(), w.points[i].y()), 255, 2 * radius - 1);
    }
    result.whiskers.push_back(std::move(w));
  }
}

void find_objects(const Maps& m, const WhiskerDetectionOptions& o, Scratch& scratch,
                  WhiskerDetection& result) {
  // What a whisker can touch: dark objects at the light smoothing's sharpness (the heavily
  // smoothed dark mask lies pixels inside a pole's edge: 5.8 px from a whisker pressed against an
  // 8 px pole) that come no nearer the face than twice the pad band (its outline, fur and
  // shadows are darker at this sharpness: a tip over the cheek is no contact; shared video, a
  // shadow 5-10 px off the cheek read as 16 contact frames of a whisker that touches nothing).
  cv::Mat &objects = scratch.objects, &object_labels = scratch.object_labels;
  cv::compare(m.smooth, dark_threshold(o.object_fraction, result.backlight, result.dark_level),
              objects, cv::CMP_LT);
  const int reach = 2 * static_cast<int>(std::lround(kFixed.pad_band_px)) + 1;
  const detail::EllipseDilation near_face(m.face, reach);
  const int object_count = cv::connectedComponents(objects, object_labels, 8, CV_32S);
  std::vector<char> touches_face(static_cast<std::size_t>(object_count), 0);
  for (int y = 0; y < objects.rows; ++y) {
    for (int x = 0; x < objects.cols; ++x) {
      // Label 0 (not an object) is never cleared; an object's label once is enough.
      const int label = object_labels.at<int>(y, x);
      if (label != 0 && !touches_face[label] && near_face.covers(x, y)) touches_face[label] = 1;
    }
  }
  for (int y = 0; y < objects.rows; ++y) {
    for (int x = 0; x < objects.cols; ++x) {
      if (touches_face[object_labels.at<int>(y, x)]) objects.at<std::uint8_t>(y, x) = 0;
    }
  }
  if (cv::countNonZero(objects) > 0) {
    cv::Mat &not_objects = scratch.not_objects, &distance = scratch.object_distance;
    cv::bitwise_not(objects, not_objects);
    cv::distanceTransform(not_objects, distance, cv::DIST_L2, cv::DIST_MASK_PRECISE);
    cv::min(distance, 255.0, distance);
    result.object_distance.assign(static_cast<std::size_t>(distance.total()), 0.0f);
    for (int y = 0; y < distance.rows; ++y) {
      std::copy(distance.ptr<float>(y), distance.ptr<float>(y) + distance.cols,
                result.object_distance.begin() + static_cast<std::ptrdiff_t>(y) * distance.cols);
    }
  }
}

}  // namespace

struct WhiskerDetectionWorkspace::Buffers {
  Maps maps;
  Scratch scratch;
  int detections = 0;
  int full_rebuilds = 0;
};

WhiskerDetectionWorkspace::WhiskerDetectionWorkspace() : buffers_(std::make_unique<Buffers>()) {}
WhiskerDetectionWorkspace::~WhiskerDetectionWorkspace() = default;
WhiskerDetectionWorkspace::WhiskerDetectionWorkspace(WhiskerDetectionWorkspace&&) noexcept =
    default;
WhiskerDetectionWorkspace& WhiskerDetectionWorkspace::operator=(
    WhiskerDetectionWorkspace&&) noexcept = default;
int WhiskerDetectionWorkspace::detections() const {
  return buffers_->detections;
}
int WhiskerDetectionWorkspace::full_rebuilds() const {
  return buffers_->full_rebuilds;
}

WhiskerDetection detect_whiskers(const ImageView& frame, const WhiskerDetectionOptions& o) {
  WhiskerDetectionWorkspace workspace;
  return detect_whiskers(frame, o, workspace);
}

WhiskerDetection detect_whiskers(const ImageView& frame, const WhiskerDetectionOptions& o,
                                 WhiskerDetectionWorkspace& workspace) {
  WhiskerDetection result;
  if (auto err = o.validate()) {
    result.error = *err;
    return result;
  }
  if (!frame.valid() || frame.width < 16 || frame.height < 16) {
    result.error = "whisker detection: the frame is empty or smaller than 16 x 16 pixels";
    return result;
  }
  WhiskerDetectionWorkspace::Buffers& buffers = workspace.buffers();
  Maps& m = buffers.maps;
  ++buffers.detections;
  // The ridge maps are first built only where the stages read them (kReadDepth); should a stage
  // read deeper into a dark region, everything is done again with them built everywhere, so the
  // result is the same as with the whole frame's maps.
  FaceSide side = o.face;
  for (const bool by_depth : {true, false}) {
    result = WhiskerDetection{};
    side = o.face;
    build_maps(frame, o, by_depth, &side, &result.backlight, &result.dark_level, m,
               buffers.scratch);
    result.face = side;
    result.noise_percent = m.noise;
    result.seed_contrast = m.seed;
    result.follow_contrast = m.follow;
    if (cv::countNonZero(m.face) == 0) {
      result.error = std::string("whisker detection: no dark region touches the ") +
                     to_string(side) + " border (no face); is the face on another side?";
      return result;
    }
    const std::vector<Seed> seeds = find_seeds(m);
    result.seeds = static_cast<int>(seeds.size());
    std::vector<Candidate> found = trace_seeds(m, o, seeds, buffers.scratch.claimed, result);
    drop_off_pad(found, o, result);
    accept_longest(found, m, o, buffers.scratch.taken, result);
    if (!m.missed) break;
    ++buffers.full_rebuilds;
  }
  find_objects(m, o, buffers.scratch, result);

  // Identities in order along the face's edge: by the follicle's coordinate along that border.
  const bool vertical = side == FaceSide::kLeft || side == FaceSide::kRight;
  std::sort(result.whiskers.begin(), result.whiskers.end(),
            [&](const DetectedWhisker& a, const DetectedWhisker& b) {
              const double ka = vertical ? a.follicle.y() : a.follicle.x();
              const double kb = vertical ? b.follicle.y() : b.follicle.x();
              return ka < kb;
            });
  return result;
}

}  // namespace sinew::rt
