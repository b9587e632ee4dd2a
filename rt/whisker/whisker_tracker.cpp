#include "rt/whisker/whisker_tracker.hpp"

#include "common/detail/field_error.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

namespace sinew::rt {

namespace {

std::string field_error(const char* field, double value, const char* constraint) {
  return common::detail::field_error("whisker tracker: ", field, value, constraint);
}

// Arc lengths along a polyline.
std::vector<double> arc_lengths(const std::vector<Eigen::Vector2d>& pts) {
  std::vector<double> s(pts.size(), 0.0);
  for (std::size_t i = 1; i < pts.size(); ++i) s[i] = s[i - 1] + (pts[i] - pts[i - 1]).norm();
  return s;
}

// Unit direction of a polyline from its first point to its point at arc length `along` (or its
// last point).
Eigen::Vector2d direction_at_start(const std::vector<Eigen::Vector2d>& pts, double along) {
  std::size_t k = 1;
  double s = 0.0;
  while (k + 1 < pts.size() && s < along) {
    s += (pts[k] - pts[k - 1]).norm();
    ++k;
  }
  const Eigen::Vector2d d = pts[k] - pts.front();
  return d.norm() > 0.0 ? Eigen::Vector2d(d.normalized()) : Eigen::Vector2d(1.0, 0.0);
}

// Squared distance from p to segment ab.
double segment_distance_sq(const Eigen::Vector2d& p, const Eigen::Vector2d& a,
                           const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double len_sq = ab.squaredNorm();
  const double t = len_sq > 0.0 ? std::clamp((p - a).dot(ab) / len_sq, 0.0, 1.0) : 0.0;
  return (a + t * ab - p).squaredNorm();
}

// The whisker's first-frame centreline resampled to `elements` equal chords (follicle first).
Eigen::Matrix2Xd resample(const std::vector<Eigen::Vector2d>& pts, int elements) {
  std::vector<double> s(pts.size(), 0.0);
  for (std::size_t i = 1; i < pts.size(); ++i) s[i] = s[i - 1] + (pts[i] - pts[i - 1]).norm();
  Eigen::Matrix2Xd nodes(2, elements + 1);
  std::size_t seg = 0;
  for (int k = 0; k <= elements; ++k) {
    const double target = s.back() * k / elements;
    while (seg + 2 < pts.size() && s[seg + 1] < target) ++seg;
    const double len = s[seg + 1] - s[seg];
    const double t = len > 0.0 ? std::clamp((target - s[seg]) / len, 0.0, 1.0) : 0.0;
    nodes.col(k) = (1.0 - t) * pts[seg] + t * pts[seg + 1];
  }
  return nodes;
}

// The tracker's fixed sizes, distances and fractions (once WhiskerTrackerOptions fields that no
// tool, test or user set; issue 48 counts every option a user could tune), with the reason for
// each value.
struct TrackerConstants {
  // Elements per whisker: its length / element_length_px, within [min_elements, max_elements]
  // (12 px: the search lines of an element see its curvature; 16 elements keep ten whiskers
  // within the latency budget).
  double element_length_px = 12.0;
  int min_elements = 4;
  int max_elements = 16;
  // associate(): the follicle distance and the angle between first directions that cost as much
  // as leaving a whisker unmatched (a pair is taken below both in quadrature), pixels and
  // degrees; the largest motion of the pad between the whiskers' last fits and the detection,
  // pixels; and how near a fit's nodes must lie to its detection to be kept, pixels.
  double associate_follicle_px = 10.0;
  double associate_angle_deg = 30.0;
  double reacquire_radius_px = 30.0;
  double associate_on_px = 3.0;
  // A detection shorter than this fraction of a whisker's length places a whisker whose refit
  // failed only as lost (its outer nodes would be guessed) and does not refit a stray.
  double associate_cover_fraction = 0.6;
  // A kept fit with fewer than this fraction of its nodes on a detection that covers it is
  // fitted again from the detection, and replaced when the refit stays on it (a pole-pressed
  // whisker's fit had stayed ok with its far half 28 px off).
  double associate_stray_fraction = 0.8;
  // One ridge, one whisker: two fits within claim_px of each other over more than
  // claim_fraction of a fit's nodes share a ridge (the header comment of WhiskerTracker).
  double claim_px = 1.5;
  double claim_fraction = 0.5;
};
constexpr TrackerConstants kFixed{};

}  // namespace

TrackerOptions WhiskerTrackerOptions::default_tracker_options() {
  TrackerOptions t;
  t.observation = ObservationMode::kDarkRidge;
  t.start_end = StartEnd::kDarkRegion;
  // Per cent of the local backlight: a 5-grey-level whisker on a 150 backlight is 3.3 %.
  t.min_strength = 1.2;
  // Four search lines per element, each averaging 9 pixel rows along the whisker (noise ÷ 3):
  // fewer, wider lines see a faint ridge as well as many narrow ones and cost less. Measured
  // (2026-12-05), samples per element / band, 8/2 (before) → 4/4: ten rendered whiskers
  // (bench_whisker_latency, one core, alternated) median 1.95–1.99 → 1.26–1.36 ms (0.68×; 0.92 ms
  // in a faster phase of the machine where 8/2 took 1.44), 0.86 → 0.39 px from the truth, ok
  // 99.3 → 99.7 %; rendered pads good 99.6 / 98.7 → 99.6 / 98.0 % (still / moving head); sliding
  // pole moment / force median 8.9 / 12.1 → 8.1 / 12.0 %; the shared video and its mirror images
  // (scripts/whisker_variants.py, % of all whisker-frames on a ridge, mean) 95.1 → 95.1. 2/8 is
  // faster still (0.54×, 0.33 px, the video 95.6 %) but loses the moving pad (97.2 % good) and
  // the sliding pole's moment (14.1 %); 3/5 the video (94.8 %), 3/6 the soft face edge below.
  t.samples_per_element = 4;
  t.band_px = 4;
  // The follicle's search along the whisker keeps a narrow band: a wide one averages the backlight
  // beside the whisker into its fall into the face (with ±8 px a soft, oblique face edge gave no
  // step above dark_region_min_step, and the whisker slid out of the face by 50 px).
  t.end_band_px = 2;
  t.line_surround_px = 3;
  // Neighbours run 3–5 px apart near the face: a wide first search would take the strongest.
  t.search_range_px = 6;
  t.first_search_range_px = 10;
  t.verify_forces = false;
  // A line counts as the whisker only with 60 % of its typical response (the default 40 % let a
  // faint whisker's fit stay ok on noise; docs/tracker.md, "Defaults").
  t.min_relative_strength = 0.6;
  // The follicle's observation holds the whole whisker along itself: weigh it as an element.
  t.end_weight = t.samples_per_element;
  // Where a whisker enters the face obliquely, or the fur's edge is soft beside a dense cluster,
  // the fall into the face along the whisker is 6-7 grey levels per pixel (shared video, frame
  // 228: 62, 58, 50, 44, 38, 31 on a ~90 backlight); with the general 10 the follicle's search
  // found nothing there, nothing held the whisker along itself, and the constant-velocity
  // prediction slid it out of the face by 12 px a frame. 6 is 4.7σ of the band-averaged central
  // difference at the rendered pads' noise (σ 4). Measured on the real video and its three
  // mirror images (scripts/whisker_variants.py, % of all whisker-frames on a ridge, mean):
  // 10: 91.4, 8: 92.9, 6: 95.1, 5: 95.1, 4: 95.2; follicle jumps 188, 140, 68, 62, 61.
  t.dark_region_min_step = 6.0;
  // Lines along the normal right from the follicle on (TrackerOptions::start_clearance_px 0):
  // they bias the follicle angle (whiskers turning rigidly ±10° about their follicles read 0.89
  // of the true turn on the sliding-pole sequence, 1.05-1.09 in tests/rt/test_whisker.cpp's
  // scene; with a 6 px clearance 1.006 and 0.99-1.04), but without them the shared video's
  // follicles hold worse (on a ridge 95.2 → 94.5 % of all whisker-frames, lost 40 → 48;
  // docs/tracker.md, "The follicle angle"), so the clearance is opt-in until the ridge measure
  // itself is unbiased there.
  t.start_clearance_px = 0.0;
  // Ridge depth next to the follicle below the darker side (TrackerOptions::
  // start_mean_surround_px 0). Within 6 px of it the face's soft, curved edge moves the darker
  // side's peak sideways (rendered whisker, true centreline and normal: 0.12-0.17 px at 1.5-4.5 px
  // from the follicle; below both sides' mean 0.01-0.03 px). Measured 2026-12-06 with 6 px
  // (contact moment about the follicle, median error; rest frame 30 / 20 rest frames): sliding
  // pole without noise 20.3 / 21.4 -> 9.2 / 12.4 %, at sigma 4 8.3 / 19.3 -> 8.9 / 13.8 %; still
  // pad (rest 20 / 35 / 20 frames) 24.8 / 15.0 / 16.9 -> 13.9 / 12.4 / 13.7 % (90th percentile
  // 106 / 65 / 102 -> 51 / 37 / 51 %); the shared video and its mirrors 95.1 -> 95.2 % of all
  // whisker-frames on a ridge, follicle jumps 46. Not the default yet: three whisker safety tests
  // fail with it (a vanished whisker reported ok on a crossing rod, a hidden whisker not taken
  // back, a follicle passing its neighbours not flagged; docs/tracker.md).
  t.start_mean_surround_px = 0.0;
  return t;
}

std::optional<std::string> WhiskerTrackerOptions::validate() const {
  if (auto err = tracker.validate()) return "whisker tracker: " + *err;
  if (!(max_jump_px > 0.0)) return field_error("max_jump_px", max_jump_px, "must be > 0");
  if (!(associate_home_px >= 0.0))
    return field_error("associate_home_px", associate_home_px, "must be >= 0");
  if (!(associate_contrast_ratio == 0.0 || associate_contrast_ratio > 1.0)) {
    return field_error("associate_contrast_ratio", associate_contrast_ratio, "must be 0 or > 1");
  }
  if (!(associate_min_length_fraction >= 0.0 && associate_min_length_fraction <= 1.0)) {
    return field_error("associate_min_length_fraction", associate_min_length_fraction,
                       "must be in [0, 1]");
  }
  if (!(held_ridge_px >= 0.0)) {
    return field_error("held_ridge_px", held_ridge_px, "must be >= 0");
  }
  if (!(associate_pair_px >= 0.0)) {
    return field_error("associate_pair_px", associate_pair_px, "must be >= 0");
  }
  if (!(follicle_order_px >= 0.0)) {
    return field_error("follicle_order_px", follicle_order_px, "must be >= 0");
  }

  return std::nullopt;
}

WhiskerTracker::WhiskerTracker(const std::vector<std::vector<Eigen::Vector2d>>& whiskers,
                               WhiskerTrackerOptions options)
    : options_(options) {
  if (auto err = options_.validate()) {
    error_ = *err;
    return;
  }
  common::BeamMaterial material;
  const double h = WhiskerTrackerOptions::kModelSectionHeightPx;
  material.E = WhiskerTrackerOptions::kModelYoungModulus;
  material.G = material.E / 2.6;
  material.A = h;
  material.I = h * h * h / 12.0;
  trackers_.reserve(whiskers.size());
  for (std::size_t w = 0; w < whiskers.size(); ++w) {
    const auto& pts = whiskers[w];
    double length = 0.0;
    for (std::size_t i = 1; i < pts.size(); ++i) length += (pts[i] - pts[i - 1]).norm();
    if (pts.size() < 2 || !(length >= 2.0)) {
      error_ = "whisker " + std::to_string(w) + ": needs at least 2 points and 2 px of length";
      trackers_.clear();
      return;
    }
    const int elements =
        std::clamp(static_cast<int>(std::lround(length / kFixed.element_length_px)),
                   kFixed.min_elements, kFixed.max_elements);
    trackers_.emplace_back(common::BeamDescription::uniform(resample(pts, elements), material),
                           options_.tracker);
    if (!trackers_.back().valid()) {
      error_ = "whisker " + std::to_string(w) + ": " + trackers_.back().error();
      trackers_.clear();
      return;
    }
  }
  results_.resize(trackers_.size());
  moved_px_.assign(trackers_.size(), 0.0);
  lost_run_.assign(trackers_.size(), 0);
  previous_.resize(trackers_.size());
  for (std::size_t w = 0; w < trackers_.size(); ++w) previous_[w] = trackers_[w].state();
  boxes_.resize(trackers_.size());
  order_.resize(trackers_.size());
  for (std::size_t w = 0; w < trackers_.size(); ++w) order_[w] = static_cast<int>(w);
  fitted_.assign(trackers_.size(), 0);
  held_.assign(trackers_.size(), 0);
  held_reach_.resize(trackers_.size());
  anchor_follicle_.resize(trackers_.size());
  anchor_direction_.resize(trackers_.size());
  home_follicle_.resize(trackers_.size());
  contrast_.assign(trackers_.size(), 0.0);
  for (std::size_t w = 0; w < trackers_.size(); ++w) {
    home_follicle_[w] = whiskers[w].front();
    anchor_follicle_[w] = whiskers[w].front();
    anchor_direction_[w] =
        direction_at_start(whiskers[w], first_element_length(static_cast<int>(w)));
  }
}

bool WhiskerTracker::mostly_near(int a, int b) const {
  // Whether more than claim_fraction of whisker a's nodes lie within claim_px of whisker b's node
  // polyline. A node outside b's box widened to claim_px is far without a distance; the count
  // stops as soon as the answer is known (whiskers that fan out from the pad decide within their
  // first nodes).
  const Tracker& ta = trackers_[a];
  const Tracker& tb = trackers_[b];
  const double limit_sq = kFixed.claim_px * kFixed.claim_px;
  const Eigen::Vector2d widen = Eigen::Vector2d::Constant(0.5 * kFixed.claim_px);
  const Eigen::AlignedBox2d reach(boxes_[b].min() - widen, boxes_[b].max() + widen);
  const int n = ta.num_nodes();
  const double needed = kFixed.claim_fraction * n;  // near must exceed this
  int near = 0;
  for (int i = 0; i < n; ++i) {
    if (near + (n - i) <= needed) return false;  // even all the rest would not be enough
    const Eigen::Vector2d p = ta.node_position(i);
    if (!reach.contains(p)) continue;
    double best = std::numeric_limits<double>::infinity();
    for (int j = 0; j + 1 < tb.num_nodes() && best > limit_sq; ++j) {
      best = std::min(best, segment_distance_sq(p, tb.node_position(j), tb.node_position(j + 1)));
    }
    near += best <= limit_sq;
    if (near > needed) return true;
  }
  return near > needed;
}

double WhiskerTracker::fraction_near(const Eigen::Matrix2Xd& points, int b) const {
  const Tracker& tb = trackers_[b];
  const double limit_sq = kFixed.claim_px * kFixed.claim_px;
  int near = 0;
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    double best = std::numeric_limits<double>::infinity();
    for (int j = 0; j + 1 < tb.num_nodes() && best > limit_sq; ++j) {
      best = std::min(
          best, segment_distance_sq(points.col(i), tb.node_position(j), tb.node_position(j + 1)));
    }
    near += best <= limit_sq;
  }
  return points.cols() > 0 ? static_cast<double>(near) / points.cols() : 0.0;
}

void WhiskerTracker::update_box(int w) noexcept {
  const Tracker& t = trackers_[w];
  Eigen::AlignedBox2d box;
  box.setEmpty();
  for (int i = 0; i < t.num_nodes(); ++i) box.extend(t.node_position(i));
  const Eigen::Vector2d pad = Eigen::Vector2d::Constant(0.5 * kFixed.claim_px);
  boxes_[w] = Eigen::AlignedBox2d(box.min() - pad, box.max() + pad);
}

double WhiskerTracker::moved_since_previous(int w) const noexcept {
  double moved = 0.0;
  const Eigen::VectorXd& u = trackers_[w].state();
  for (int i = 0; i < trackers_[w].num_nodes(); ++i) {
    moved = std::max(moved, (u.segment<2>(3 * i) - previous_[w].segment<2>(3 * i)).norm());
  }
  return moved;
}

void WhiskerTracker::gather_held(int except) noexcept {
  const Eigen::Vector2d widen = Eigen::Vector2d::Constant(options_.held_ridge_px);
  held_count_ = 0;
  for (int b = 0; b < num_whiskers(); ++b) {
    if (b == except || !fitted_[b] || results_[b].status == FrameStatus::kLost) continue;
    held_[held_count_] = b;
    held_reach_[held_count_++] =
        Eigen::AlignedBox2d(boxes_[b].min() - widen, boxes_[b].max() + widen);
  }
}

bool WhiskerTracker::held_by_other(const Eigen::Vector2d& p) const noexcept {
  const double r = options_.held_ridge_px;
  // A segment whose bounding box p lies more than r outside is farther than r: no distance and
  // no division for it (the 1e-6 px margin is far above the distance's rounding, so the answer
  // is the distance test's).
  const double reach = r + 1e-6;
  for (int k = 0; k < held_count_; ++k) {
    if (!held_reach_[k].contains(p)) continue;
    const Tracker& tb = trackers_[held_[k]];
    for (int j = 0; j + 1 < tb.num_nodes(); ++j) {
      const Eigen::Vector2d a = tb.node_position(j), c = tb.node_position(j + 1);
      if (p.x() < std::min(a.x(), c.x()) - reach || p.x() > std::max(a.x(), c.x()) + reach ||
          p.y() < std::min(a.y(), c.y()) - reach || p.y() > std::max(a.y(), c.y()) + reach) {
        continue;
      }
      if (segment_distance_sq(p, a, c) <= r * r) return true;
    }
  }
  return false;
}

bool WhiskerTracker::any_lost() const {
  for (const WhiskerFrame& r : results_) {
    if (r.status == FrameStatus::kLost) return true;
  }
  return false;
}

double WhiskerTracker::first_element_length(int w) const {
  const Eigen::Matrix2Xd& X = trackers_[w].model().rest_positions();
  return (X.col(1) - X.col(0)).norm();
}

double WhiskerTracker::rest_length(int w) const {
  const Eigen::Matrix2Xd& X = trackers_[w].model().rest_positions();
  double length = 0.0;
  for (int i = 1; i < X.cols(); ++i) length += (X.col(i) - X.col(i - 1)).norm();
  return length;
}

bool WhiskerTracker::runs_along(int w, const std::vector<Eigen::Vector2d>& pts) const {
  return fraction_along(w, pts) > kFixed.claim_fraction;
}

double WhiskerTracker::fraction_along(int w, const std::vector<Eigen::Vector2d>& pts) const {
  // The fraction of the fit's nodes up to the detection's length within associate_on_px of its
  // curve.
  const Tracker& t = trackers_[w];
  const double length = arc_lengths(pts).back();
  const double limit_sq = kFixed.associate_on_px * kFixed.associate_on_px;
  double s = 0.0;
  int near = 0, considered = 0;
  for (int i = 0; i < t.num_nodes(); ++i) {
    if (i > 0) s += (t.node_position(i) - t.node_position(i - 1)).norm();
    if (s > length) break;
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k + 1 < pts.size() && best > limit_sq; ++k) {
      best = std::min(best, segment_distance_sq(t.node_position(i), pts[k], pts[k + 1]));
    }
    near += best <= limit_sq;
    ++considered;
  }
  return considered > 0 ? static_cast<double>(near) / considered : 0.0;
}

Eigen::Matrix2Xd WhiskerTracker::nodes_along(int w, const std::vector<Eigen::Vector2d>& pts) const {
  // Nodes at the whisker's own rest arc lengths along the curve (past its end, along its last
  // direction).
  const Tracker& t = trackers_[w];
  const std::vector<double> s = arc_lengths(pts);
  Eigen::Matrix2Xd nodes(2, t.num_nodes());
  double target = 0.0;
  std::size_t seg = 0;
  for (int i = 0; i < t.num_nodes(); ++i) {
    if (i > 0) {
      target += (t.model().rest_positions().col(i) - t.model().rest_positions().col(i - 1)).norm();
    }
    while (seg + 2 < pts.size() && s[seg + 1] < target) ++seg;
    const double len = s[seg + 1] - s[seg];
    const double a = len > 0.0 ? (target - s[seg]) / len : 0.0;  // may exceed 1 past the end
    nodes.col(i) = pts[seg] + std::max(0.0, a) * (pts[seg + 1] - pts[seg]);
  }
  return nodes;
}

WhiskerAssociation WhiskerTracker::associate(
    const ImageView& frame, const std::vector<std::vector<Eigen::Vector2d>>& detected,
    const std::vector<double>& detected_contrast) {
  WhiskerAssociation summary;
  const int n = num_whiskers();
  std::vector<int> cand;  // usable detections
  for (std::size_t d = 0; d < detected.size(); ++d) {
    if (detected[d].size() >= 2) cand.push_back(static_cast<int>(d));
  }
  const int m = static_cast<int>(cand.size());
  summary.detected = m;
  if (n == 0 || m == 0) return summary;

  std::vector<double> detected_length(detected.size(), 0.0);
  for (int d : cand) detected_length[d] = arc_lengths(detected[d]).back();
  // The fainter of two whiskers whose follicles lie closer than associate_pair_px is matched
  // after all the others, to the detections they left.
  std::vector<char> second(n, 0);
  bool any_second = false;
  if (options_.associate_pair_px > 0.0) {
    for (int w = 0; w < n; ++w) {
      for (int v = 0; v < n && !second[w]; ++v) {
        second[w] = v != w && contrast_[w] > 0.0 && contrast_[w] < contrast_[v] &&
                    (anchor_follicle_[v] - anchor_follicle_[w]).norm() < options_.associate_pair_px;
      }
      any_second = any_second || second[w];
    }
  }
  std::vector<int> match;
  if (!any_second) {
    match = match_detections(detected, detected_contrast, cand, detected_length, {}, summary);
  } else {
    std::vector<char> first(n);
    for (int w = 0; w < n; ++w) first[w] = !second[w];
    match = match_detections(detected, detected_contrast, cand, detected_length, first, summary);
    std::vector<char> used(detected.size(), 0);
    for (int w = 0; w < n; ++w) {
      if (match[w] >= 0) used[match[w]] = 1;
    }
    std::vector<int> left;
    for (int d : cand) {
      if (!used[d]) left.push_back(d);
    }
    if (!left.empty()) {
      WhiskerAssociation unused = summary;  // the pad's shift stays the first matching's
      const std::vector<int> later =
          match_detections(detected, detected_contrast, left, detected_length, second, unused);
      for (int w = 0; w < n; ++w) {
        if (second[w]) match[w] = later[w];
      }
    }
  }
  // A whisker that tracking kept keeps its fit, unless the fit strays from a detection that
  // covers the whisker and a refit from the detection stays on it (replacing strays without that
  // test lowered the shared video's on-ridge fraction, 76.2 % -> 68.2 %: a 30 fps frame's
  // detections often run onto a crossing whisker). A lost one restarts on its detection and is
  // fitted to this frame again; a refit that leaves the detection (slides along it, onto a
  // neighbour) is undone: the whisker stays on its detection, reported not converged.
  for (int w = 0; w < n; ++w) {
    if (match[w] < 0) continue;
    ++summary.matched;
    if (detected_contrast.size() == detected.size() && detected_contrast[match[w]] > 0.0) {
      // The geometric running mean of the matched detections' contrasts (a blurred frame reads
      // a whisker fainter, so one frame's reading is not its darkness).
      constexpr double kWeight = 0.2;
      const double c = detected_contrast[match[w]];
      contrast_[w] =
          contrast_[w] > 0.0
              ? std::exp((1.0 - kWeight) * std::log(contrast_[w]) + kWeight * std::log(c))
              : c;
    }
    take_detection(w, frame, detected[match[w]], detected_length[match[w]], summary);
  }
  // A whisker no detection matched keeps its fit unless the fit runs along a detection another
  // whisker took: then it is on its neighbour.
  std::vector<char> taken(detected.size(), 0);
  for (int w = 0; w < n; ++w) {
    if (match[w] >= 0) taken[match[w]] = 1;
  }
  for (int w = 0; w < n; ++w) {
    if (match[w] >= 0 || results_[w].status == FrameStatus::kLost) continue;
    for (std::size_t d = 0; d < detected.size(); ++d) {
      if (!taken[d] || detected[d].size() < 2 || !runs_along(w, detected[d])) continue;
      trackers_[w].reject_last_frame();
      results_[w].status = FrameStatus::kLost;
      results_[w].on_neighbour = true;
      break;
    }
  }
  update_geometry();
  return summary;
}

std::vector<int> WhiskerTracker::match_detections(
    const std::vector<std::vector<Eigen::Vector2d>>& detected,
    const std::vector<double>& detected_contrast, const std::vector<int>& cand,
    const std::vector<double>& detected_length, const std::vector<char>& allowed,
    WhiskerAssociation& summary) const {
  const int n = num_whiskers();
  const int m = static_cast<int>(cand.size());
  // Follicles never change their order along the face. The order is read along the principal
  // axis of the anchored follicles (the whisker pad's row, whatever side the face is on).
  const Eigen::Vector2d axis = pad_axis();
  std::vector<int> order_w(n), order_d(m);
  for (int w = 0; w < n; ++w) order_w[w] = w;
  for (int k = 0; k < m; ++k) order_d[k] = cand[k];
  std::sort(order_w.begin(), order_w.end(), [&](int a, int b) {
    return anchor_follicle_[a].dot(axis) < anchor_follicle_[b].dot(axis);
  });
  std::sort(order_d.begin(), order_d.end(), [&](int a, int b) {
    return detected[a].front().dot(axis) < detected[b].front().dot(axis);
  });

  // Each tracked whisker's follicle and first direction, each detection's over the same arc.
  // Each whisker is matched from where a detection last confirmed it (its anchor), not from its
  // fit, which may have slid or been lost since.
  const std::vector<Eigen::Vector2d>& fw = anchor_follicle_;
  const std::vector<Eigen::Vector2d>& dw = anchor_direction_;
  // cost(i, k): whisker order_w[i] against detection order_d[k] under a common shift of the pad.
  const double fs = kFixed.associate_follicle_px;
  const double as = kFixed.associate_angle_deg * M_PI / 180.0;
  std::vector<double> angle(static_cast<std::size_t>(n) * m);
  for (int i = 0; i < n; ++i) {
    const int w = order_w[i];
    const double first = first_element_length(w);
    for (int k = 0; k < m; ++k) {
      const Eigen::Vector2d dd = direction_at_start(detected[order_d[k]], first);
      angle[i * m + k] = std::acos(std::clamp(dd.dot(dw[w]), -1.0, 1.0));
      // A detection much shorter than the whisker (a faint or blurred stretch ended its trace)
      // cannot place it: nodes past its end would be guessed.
      if (detected_length[order_d[k]] < options_.associate_min_length_fraction * rest_length(w) ||
          (!allowed.empty() && !allowed[w])) {
        angle[i * m + k] = std::numeric_limits<double>::infinity();
      }
    }
  }
  // Where each whisker's first follicle lies now: the first follicles moved by the rigid motion
  // (least squares) that brings them onto the anchors.
  std::vector<Eigen::Vector2d> home(n);
  {
    Eigen::Vector2d mh = Eigen::Vector2d::Zero(), ma = Eigen::Vector2d::Zero();
    for (int w = 0; w < n; ++w) {
      mh += home_follicle_[w];
      ma += fw[w];
    }
    mh /= n;
    ma /= n;
    double sc = 0.0, ss = 0.0;  // Σ h·a and Σ h×a of the centred points
    for (int w = 0; w < n; ++w) {
      const Eigen::Vector2d h = home_follicle_[w] - mh, a = fw[w] - ma;
      sc += h.dot(a);
      ss += h.x() * a.y() - h.y() * a.x();
    }
    const double phi = n > 1 ? std::atan2(ss, sc) : 0.0;
    const Eigen::Rotation2Dd rotation(phi);
    for (int w = 0; w < n; ++w) home[w] = ma + rotation * (home_follicle_[w] - mh);
  }
  const double hs = options_.associate_home_px;
  auto pair_cost = [&](int i, int k, const Eigen::Vector2d& shift) {
    const Eigen::Vector2d d = detected[order_d[k]].front();
    const double dist = (fw[order_w[i]] + shift - d).norm() / fs;
    const double ang = angle[i * m + k] / as;
    double cost = dist * dist + ang * ang;
    // A whisker's darkness is its own: a darker neighbour's detection is not its.
    if (options_.associate_contrast_ratio > 1.0 && detected_contrast.size() == detected.size() &&
        contrast_[order_w[i]] > 0.0 && detected_contrast[order_d[k]] > 0.0) {
      const double r = std::log(detected_contrast[order_d[k]] / contrast_[order_w[i]]) /
                       std::log(options_.associate_contrast_ratio);
      cost += r * r;
    }
    if (hs > 0.0) {
      const double far = (home[order_w[i]] + shift - d).norm() / hs;
      cost += far * far;
    }
    return cost;
  };
  // Order-preserving matching (skips allowed on both sides) by dynamic programming: a pair is
  // taken when its cost is below 1 (a skip on each side costs 1/2).
  std::vector<double> dp(static_cast<std::size_t>(n + 1) * (m + 1));
  std::vector<char> step(dp.size());
  auto solve = [&](const Eigen::Vector2d& shift) {
    const int cols = m + 1;
    for (int i = 0; i <= n; ++i) {
      for (int k = 0; k <= m; ++k) {
        double best = std::numeric_limits<double>::infinity();
        char how = 0;
        if (i == 0 && k == 0) best = 0.0;
        if (i > 0 && dp[(i - 1) * cols + k] + 0.5 < best) {
          best = dp[(i - 1) * cols + k] + 0.5;
          how = 1;  // whisker unmatched
        }
        if (k > 0 && dp[i * cols + k - 1] + 0.5 < best) {
          best = dp[i * cols + k - 1] + 0.5;
          how = 2;  // detection unmatched
        }
        if (i > 0 && k > 0) {
          const double c = pair_cost(i - 1, k - 1, shift);
          if (c < 1.0 && dp[(i - 1) * cols + k - 1] + c < best) {
            best = dp[(i - 1) * cols + k - 1] + c;
            how = 3;
          }
        }
        dp[i * cols + k] = best;
        step[i * cols + k] = how;
      }
    }
    return dp[n * cols + m];
  };
  // The shift: none (the fits of this frame are where the whiskers are) or the one that brings a
  // whisker's follicle onto a detection's, whichever matches best.
  Eigen::Vector2d best_shift = Eigen::Vector2d::Zero();
  double best_total = solve(best_shift);
  for (int i = 0; i < n; ++i) {
    for (int k = 0; k < m; ++k) {
      if (angle[i * m + k] > as) continue;
      const Eigen::Vector2d shift = detected[order_d[k]].front() - fw[order_w[i]];
      if (shift.norm() > kFixed.reacquire_radius_px) continue;
      const double total = solve(shift);
      if (total < best_total - 1e-12) {
        best_total = total;
        best_shift = shift;
      }
    }
  }
  solve(best_shift);
  summary.shift = best_shift;
  std::vector<int> match(n, -1);
  for (int i = n, k = m; i > 0 || k > 0;) {
    const char how = step[i * (m + 1) + k];
    if (how == 3) {
      match[order_w[i - 1]] = order_d[k - 1];
      --i;
      --k;
    } else if (how == 1) {
      --i;
    } else {
      --k;
    }
  }
  return match;
}

bool WhiskerTracker::on_detection(int w, const std::vector<Eigen::Vector2d>& pts) const {
  return runs_along(w, pts) &&
         (trackers_[w].node_position(0) - pts.front()).norm() <= kFixed.associate_on_px;
}

void WhiskerTracker::take_detection(int w, const ImageView& frame,
                                    const std::vector<Eigen::Vector2d>& pts, double detected_length,
                                    WhiskerAssociation& summary) {
  anchor_follicle_[w] = pts.front();
  anchor_direction_[w] = direction_at_start(pts, first_element_length(w));
  WhiskerFrame& r = results_[w];
  const Eigen::Matrix2Xd nodes = nodes_along(w, pts);
  const bool covers = detected_length >= kFixed.associate_cover_fraction * rest_length(w);
  // Restarts the whisker on its detection and fits it to the frame again: whether the fit stayed
  // on the detection.
  auto refit = [&]() {
    trackers_[w].restart_at(nodes, options_.associate_narrow_refit);
    r.summary = trackers_[w].track(frame);
    r.status = r.summary.status;
    return r.status != FrameStatus::kLost && on_detection(w, pts);
  };
  if (r.status != FrameStatus::kLost) {
    // A kept fit that strays from a detection covering its whisker is tried again from the
    // detection; the refit replaces it if it stays on the detection, else the whisker is placed
    // on the detection without a fit (associate_place_strays) or the stray is kept.
    if (!covers || fraction_along(w, pts) >= kFixed.associate_stray_fraction) return;
    if (!options_.associate_place_strays) {
      const Tracker kept = trackers_[w];
      const WhiskerFrame kept_result = r;
      if (!refit()) {
        trackers_[w] = kept;
        r = kept_result;
        return;
      }
    } else if (!refit()) {
      // The stray is not kept either: the whisker is where its detection is.
      trackers_[w].restart_at(nodes);
      r.status = FrameStatus::kNotConverged;
    }
    r.reacquired = true;
    ++summary.restarted;
    return;
  }
  if (!refit()) {
    trackers_[w].restart_at(nodes);
    // Placed without a fit: only where the detection covers the whisker; a short one would
    // leave its outer nodes guessed.
    r.status = covers ? FrameStatus::kNotConverged : FrameStatus::kLost;
  }
  r.reacquired = true;
  r.jumped = false;
  r.on_neighbour = false;
  if (r.status != FrameStatus::kLost) lost_run_[w] = 0;
  ++summary.restarted;
}

Eigen::Vector2d WhiskerTracker::pad_axis() const noexcept {
  const int n = num_whiskers();
  if (n < 2) return Eigen::Vector2d(1.0, 0.0);
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (int w = 0; w < n; ++w) mean += anchor_follicle_[w];
  mean /= n;
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (int w = 0; w < n; ++w) {
    const Eigen::Vector2d q = anchor_follicle_[w] - mean;
    cov += q * q.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
  return eig.eigenvectors().col(1);
}

void WhiskerTracker::keep_follicle_order() noexcept {
  // The order is the anchors' (where a detection last confirmed each whisker, or its initial
  // curve): a fit may creep past a neighbour a fraction of a pixel per frame, so the order of
  // the last frame would not show it.
  const int n = num_whiskers();
  const Eigen::Vector2d axis = pad_axis();
  const double tol = options_.follicle_order_px;
  // A whisker lost on this frame or the two before still marks where its follicle is (its last
  // good fit): a neighbour may not pass it while it is not seen.
  auto marks = [&](int w) { return results_[w].status != FrameStatus::kLost || lost_run_[w] < 3; };
  for (int a = 0; a < n; ++a) {
    if (results_[a].status == FrameStatus::kLost) continue;
    for (int b = 0; b < n; ++b) {
      if (b == a || !marks(b)) continue;
      const bool b_kept = results_[b].status != FrameStatus::kLost;
      if (b_kept && b < a) continue;  // each pair of kept fits once
      const double anchored = (anchor_follicle_[a] - anchor_follicle_[b]).dot(axis);
      const double now = (trackers_[a].node_position(0) - trackers_[b].node_position(0)).dot(axis);
      if (!((anchored > tol && now < -tol) || (anchored < -tol && now > tol))) continue;
      // Of two kept fits, the one farther from its anchor slid.
      const double off_a = (trackers_[a].node_position(0) - anchor_follicle_[a]).norm();
      const double off_b = (trackers_[b].node_position(0) - anchor_follicle_[b]).norm();
      const int loser = !b_kept || off_a > off_b ? a : b;
      trackers_[loser].reject_last_frame();
      results_[loser].status = FrameStatus::kLost;
      results_[loser].out_of_order = true;
      if (loser == a) break;
    }
  }
}

void WhiskerTracker::update_geometry() noexcept {
  for (int w = 0; w < num_whiskers(); ++w) {
    const Tracker& t = trackers_[w];
    WhiskerFrame& r = results_[w];
    r.follicle = t.node_position(0);
    r.tip = t.node_position(t.num_nodes() - 1);
    r.length_px = 0.0;
    for (int i = 1; i < t.num_nodes(); ++i) {
      r.length_px += (t.node_position(i) - t.node_position(i - 1)).norm();
    }
  }
}

void WhiskerTracker::track_one(const ImageView& frame, int w) noexcept {
  // Held ridges: those of the whiskers fitted before w on this frame.
  class HeldRidges final : public CandidateExclusion {
   public:
    explicit HeldRidges(const WhiskerTracker& owner) : owner_(owner) {}
    bool excluded(const Eigen::Vector2d& p) const noexcept override {
      return owner_.held_by_other(p);
    }

   private:
    const WhiskerTracker& owner_;
  };
  const HeldRidges held(*this);
  Tracker& t = trackers_[w];
  if (options_.held_ridge_px > 0.0) {
    gather_held(w);
    t.set_exclusion(&held);
  }
  WhiskerFrame& r = results_[w];
  r.summary = t.track(frame);
  t.set_exclusion(nullptr);
  r.status = r.summary.status;
  r.on_neighbour = false;
  r.out_of_order = false;
  r.reacquired = false;
  moved_px_[w] = moved_since_previous(w);
  const double allowed = options_.max_jump_px * (lost_run_[w] > 0 ? 2.0 : 1.0);
  r.jumped = r.status != FrameStatus::kLost && moved_px_[w] > allowed;
  if (r.jumped) {
    t.reject_last_frame();
    r.status = FrameStatus::kLost;
  }
  update_box(w);
  fitted_[w] = 1;
}

double WhiskerTracker::track(const ImageView& frame) noexcept {
  const auto t0 = std::chrono::steady_clock::now();
  const int n = num_whiskers();
  for (int w = 0; w < n; ++w) {
    previous_[w] = trackers_[w].state();  // same size: no allocation
    fitted_[w] = 0;
  }
  if (options_.held_ridge_px > 0.0) {
    // Brightest first (std::stable_sort would allocate; the index breaks ties).
    std::sort(order_.begin(), order_.end(), [&](int a, int b) {
      const double sa = trackers_[a].typical_strength(), sb = trackers_[b].typical_strength();
      return sa > sb || (sa == sb && a < b);
    });
  }
  for (int w : order_) track_one(frame, w);
  // One ridge, one whisker: of two fits that run along each other, the one that moved more has
  // jumped onto its neighbour.
  for (int a = 0; a < n; ++a) {
    if (results_[a].status == FrameStatus::kLost) continue;
    for (int b = 0; b < n; ++b) {
      if (b == a || results_[b].status == FrameStatus::kLost) continue;
      // Fits whose bounding boxes lie apart by more than claim_px share no node.
      if (!boxes_[a].intersects(boxes_[b]) || !mostly_near(a, b)) {
        continue;
      }
      const int loser = moved_px_[a] > moved_px_[b] ? a : b;
      trackers_[loser].reject_last_frame();
      results_[loser].status = FrameStatus::kLost;
      results_[loser].on_neighbour = true;
      if (loser == a) break;
    }
  }
  if (options_.follicle_order_px > 0.0) keep_follicle_order();
  for (int w = 0; w < n; ++w) {
    lost_run_[w] = results_[w].status == FrameStatus::kLost ? lost_run_[w] + 1 : 0;
  }
  update_geometry();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace sinew::rt
