#pragma once
/// Many whiskers at once, each a free beam (seed 000 §5.3) fitted to its own dark ridge, with a
/// stable identity and a status per frame. All memory is sized at construction for the whiskers
/// given; track() never allocates, throws or prints.
///
/// Each whisker's first node is its follicle: its end search along the tangent looks for the
/// face's edge (StartEnd::kDarkRegion), so the base moves with the face and may slide along its
/// edge but not along the whisker into the fur. Ridges are observed by their contrast relative to
/// the local backlight (ObservationMode::kDarkRidge), which neither a face's outline nor a thick
/// pole's sides answer.
///
/// A ridge is one whisker's: when a fit ends running along a neighbour's curve (within
/// 1.5 px over more than half of its nodes), the whisker that moved more this frame
/// has jumped: its fit is discarded (Tracker::reject_last_frame) and it is reported lost for the
/// frame, so identities do not swap where whiskers cross or run side by side. Before it comes to
/// that, whiskers are fitted brightest first, and each fit's search leaves out the ridges the
/// whiskers fitted before it hold this frame (held_ridge_px): a faint whisker a few pixels beside
/// a bright one would otherwise take the brighter ridge, the strongest in its search's reach.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>
#include <string>
#include <vector>

#include "rt/tracker.hpp"

namespace sinew::rt {

struct WhiskerTrackerOptions {
  /// Options of every whisker's tracker; the defaults below suit a faint whisker on a backlight.
  TrackerOptions tracker = default_tracker_options();
  /// A whisker's section in pixel units (E, and the width h of a rectangular section of depth 1):
  /// only ratios matter to the fit; forces in physical units are the read-out's business. Not
  /// options (nothing the fit does depends on them).
  static constexpr double kModelYoungModulus = 1000.0;
  static constexpr double kModelSectionHeightPx = 2.0;
  /// A fit whose node moved more than this in one frame has slid or jumped off its whisker (a
  /// free beam is anchored by nothing but its ridge): it is discarded and the frame is lost,
  /// pixels, > 0. Should exceed the true motion per frame (the search reaches
  /// tracker.first_search_range_px). A whisker lost on the frames before moved on while it was
  /// not seen: its next fit may move twice this from its last good one. (Ten rendered whiskers,
  /// half of them hidden for 5 of every 25 frames, test_no_allocation, tracked with 2 search
  /// lines of ±8 px per element: ok whisker-frames 1925 of at most ~2690 with 1× (a whisker back
  /// after the gap had turned by more and was refused until it turned back), 2660 with 2×, 2584
  /// with 3×, 2534 with (frames lost + 1)×: a larger allowance lets fits through that slid along
  /// the whisker.)
  double max_jump_px = 20.0;
  /// Identities do not walk along the pad: a detection also costs by its distance from where the
  /// whisker's first follicle lies now (the first follicles moved rigidly onto the anchors, as the
  /// head moves), as much as leaving it unmatched at this distance, pixels (0: not used).
  double associate_home_px = 0.0;
  /// A detection shorter than this fraction of a whisker's length is not matched to it, [0, 1].
  /// 0.4 (was 0.8): a 30 fps frame's detection often ends early on a blurred whisker.
  double associate_min_length_fraction = 0.4;
  /// A kept fit that strays from a detection covering its whisker (fewer than 80 % of its nodes
  /// within 3 px of it) is fitted again from the detection, and replaced when the refit stays on
  /// it (a pole-pressed whisker's fit had stayed ok with its far half 28 px off); when that refit
  /// leaves the detection too, the whisker is placed on the detection,
  /// reported not converged, instead of keeping the stray. (Shared video: the leftmost whisker
  /// of the dense cluster had slid 13 px along the face and into the fur, and stayed there `ok`
  /// for 40 frames beside its own detection; see docs/tracker.md.)
  bool associate_place_strays = true;
  /// A whisker restarted on its detection is fitted to the frame again with a narrow first search
  /// (Tracker::restart_at's narrow: ±search_range_px, the nearest candidates) instead of a lost
  /// frame's (±2 first_search_range_px, the strongest), which beside a darker neighbour takes the
  /// neighbour's ridge and leaves the detection. Shared video: whisker-frames fitted ok 1,260 ->
  /// 1,456 of 1,500 (placed without a fit 211 -> 26, lost 29 -> 18); docs/tracker.md.
  bool associate_narrow_refit = true;
  /// A whisker's darkness is its own: the matching also costs a detection by the ratio of its
  /// ridge contrast (DetectedWhisker::contrast_percent) to the whisker's (the geometric running
  /// mean over its matched detections), as much as one 10 px away when they differ
  /// by this factor, > 1 (0: not used; nor when associate() is given no contrasts). Where the
  /// detection of a faint whisker in a dense cluster is missing, the darker neighbour's is not
  /// taken for it and its identity does not walk (shared video: the median drift of a follicle
  /// from its first position 55 -> 3 px; docs/tracker.md).
  double associate_contrast_ratio = 2.0;
  /// Two whiskers whose follicles (where detections last confirmed them) lie closer than this
  /// share one place on the pad: their order along it, which the matching keeps, is not known
  /// there. The fainter of such a pair is matched after all the others, to the detections they
  /// left, pixels (0: all at once). Shared video: the faint whisker 1.4 px beside the longest,
  /// matched at once, took the longest's or its neighbour's detections in the whisking bout and
  /// ids swapped for good (95.0 % of all whisker-frames on a ridge, 86.0 % with an 18 px bridge
  /// in detection); matched second, 95.8 % with any bridge of 16-20 px, no swap (docs/tracker.md).
  double associate_pair_px = 3.0;
  /// A whisker's search drops the candidates within this distance of the node polylines of the
  /// whiskers fitted (and kept) before it on the frame, brighter ones (Tracker::typical_strength)
  /// first. Pixels (0: all candidates, in whisker order). (Also refitting a fit discarded as on
  /// its neighbour beside all the others was tried: on the shared video it was kept once in
  /// 1,800 whisker-frames.)
  double held_ridge_px = 2.0;
  /// Follicles keep their order along the whisker pad (the principal axis of the follicles a
  /// detection last confirmed, its anchors): a fit whose follicle lies past a neighbour's by more
  /// than this, where their anchors lie in the other order by more than this, slid onto another
  /// whisker; of the two, the one farther from its anchor is discarded and reported lost for the
  /// frame (a neighbour lost on this frame or the two before marks its place by its last good
  /// fit), pixels (0: no such test).
  double follicle_order_px = 1.0;

  static TrackerOptions default_tracker_options();
  std::optional<std::string> validate() const;
};

/// Per whisker and frame.
struct WhiskerFrame {
  FrameStatus status = FrameStatus::kLost;
  bool on_neighbour = false;  ///< the fit ran onto another whisker and was discarded
  bool jumped = false;        ///< the fit moved more than max_jump_px and was discarded
  bool out_of_order = false;  ///< its follicle passed a neighbour's along the pad; discarded
  bool reacquired = false;    ///< restarted on its detection by associate() on this frame
  Eigen::Vector2d follicle = Eigen::Vector2d::Zero();  ///< first node
  Eigen::Vector2d tip = Eigen::Vector2d::Zero();       ///< last node
  double length_px = 0.0;                              ///< along the fitted nodes
  FrameSummary summary;                                ///< the whisker's own tracker summary
};

/// What associate() did on one frame.
struct WhiskerAssociation {
  int detected = 0;                                 ///< detections offered
  int matched = 0;                                  ///< whiskers matched to one
  int restarted = 0;                                ///< of those, restarted on it and fitted again
  Eigen::Vector2d shift = Eigen::Vector2d::Zero();  ///< the pad's shift the matching used
};

class WhiskerTracker {
 public:
  /// whiskers: each whisker's centreline on the first frame, follicle first (e.g. the points of
  /// detect_whiskers), at least 2 points and 2 px long. Check valid().
  WhiskerTracker(const std::vector<std::vector<Eigen::Vector2d>>& whiskers,
                 WhiskerTrackerOptions options = {});

  bool valid() const { return error_.empty(); }
  const std::string& error() const { return error_; }
  int num_whiskers() const { return static_cast<int>(trackers_.size()); }
  const Tracker& whisker(int i) const { return trackers_[i]; }
  const WhiskerFrame& result(int i) const { return results_[i]; }
  /// Where a detection last confirmed whisker i (its first frame's follicle until then): what
  /// associate() matches it from.
  const Eigen::Vector2d& anchor_follicle(int i) const { return anchor_follicle_[i]; }

  /// Tracks every whisker on one frame; returns the wall time in seconds. No allocation.
  double track(const ImageView& frame) noexcept;

  /// Associates the whiskers with those detected on the frame just tracked (detect_whiskers,
  /// follicle first), for videos whose whiskers move more between frames than the search reaches
  /// (25–100 fps cameras) and to recover lost whiskers. Follicles keep their order along the face,
  /// so the matching preserves it: tracked whiskers and detections are ordered along the pad's row
  /// (the principal axis of the tracked follicles) and matched by dynamic programming, with skips
  /// on both sides, on the follicle distance and the angle between first directions under one
  /// common shift of the pad (none, or up to 30 px: the shift that matches best).
  /// A whisker whose fit runs along its detection keeps it; a lost one, or one whose fit lies
  /// elsewhere, restarts on its detection (Tracker::restart_at) and is fitted to `frame` again.
  /// A whisker no detection matches keeps its own fit, so a faint whisker detection misses on a
  /// frame is not lost by it. Detection reports no pole, lick port or face outline, so no
  /// whisker is restarted on one. detected_contrast: each detection's ridge contrast
  /// (DetectedWhisker::contrast_percent), or empty (see associate_contrast_ratio). Outside the
  /// real-time contract (allocates).
  WhiskerAssociation associate(const ImageView& frame,
                               const std::vector<std::vector<Eigen::Vector2d>>& detected,
                               const std::vector<double>& detected_contrast = {});
  /// Any whisker lost on the last tracked frame.
  bool any_lost() const;

 private:
  void update_geometry() noexcept;
  double first_element_length(int w) const;
  double rest_length(int w) const;
  // Whisker w's nodes at its rest arc lengths along a curve, follicle first.
  Eigen::Matrix2Xd nodes_along(int w, const std::vector<Eigen::Vector2d>& pts) const;
  // Whether whisker w's fit lies within 3 px of the curve along the curve's length.
  bool runs_along(int w, const std::vector<Eigen::Vector2d>& pts) const;
  // The fraction of whisker w's nodes (up to the curve's length) within 3 px of it.
  double fraction_along(int w, const std::vector<Eigen::Vector2d>& pts) const;
  // associate() in its steps: the order-preserving matching of whiskers to the usable
  // detections `cand` (detected_length: each detection's arc length; allowed: the whiskers that
  // may be matched, empty for all; per whisker, the detection's index or -1; sets summary.shift);
  // whether whisker w's fit runs along a detection from its
  // follicle on; and taking a matched detection (the anchor moves to it; a lost or straying whisker
  // restarts on it).
  std::vector<int> match_detections(const std::vector<std::vector<Eigen::Vector2d>>& detected,
                                    const std::vector<double>& detected_contrast,
                                    const std::vector<int>& cand,
                                    const std::vector<double>& detected_length,
                                    const std::vector<char>& allowed,
                                    WhiskerAssociation& summary) const;
  bool on_detection(int w, const std::vector<Eigen::Vector2d>& pts) const;
  void take_detection(int w, const ImageView& frame, const std::vector<Eigen::Vector2d>& pts,
                      double detected_length, WhiskerAssociation& summary);
  // Whether more than half of whisker a's nodes lie within 1.5 px (the claim distance) of whisker
  // b's node polyline (reads boxes_ of this frame).
  bool mostly_near(int a, int b) const;
  // The whisker pad's row: the principal axis of the follicles detections last confirmed.
  Eigen::Vector2d pad_axis() const noexcept;
  // See WhiskerTrackerOptions::follicle_order_px.
  void keep_follicle_order() noexcept;
  // Fraction of the points within the claim distance of whisker b's node polyline.
  double fraction_near(const Eigen::Matrix2Xd& points, int b) const;
  // boxes_[w] from whisker w's nodes now.
  void update_box(int w) noexcept;
  // The largest node displacement of whisker w since previous_[w].
  double moved_since_previous(int w) const noexcept;
  // Tracks whisker w on the frame (the jump test included; sets boxes_[w] and fitted_[w]).
  void track_one(const ImageView& frame, int w) noexcept;
  // held_ = the whiskers other than `except` fitted and kept on this frame, with their boxes
  // widened by held_ridge_px (gathered once per fit: they do not change while whisker `except`
  // is fitted, and held_by_other is asked once per candidate).
  void gather_held(int except) noexcept;
  // Whether p lies within held_ridge_px of the node polyline of a whisker in held_.
  bool held_by_other(const Eigen::Vector2d& p) const noexcept;

  WhiskerTrackerOptions options_;
  std::string error_;
  std::vector<Tracker> trackers_;
  std::vector<WhiskerFrame> results_;
  std::vector<double> moved_px_;  // max node displacement this frame, per whisker
  std::vector<int> lost_run_;     // frames in a row each whisker has been lost
  std::vector<Eigen::VectorXd> previous_;
  std::vector<Eigen::AlignedBox2d>
      boxes_;                 // each fit's node bounding box, half the claim distance wider
  std::vector<int> order_;    // whiskers in the order they are fitted
  std::vector<char> fitted_;  // fitted on this frame yet
  std::vector<int> held_;     // gather_held: whiskers, the first held_count_ used
  std::vector<Eigen::AlignedBox2d> held_reach_;  // ... and their boxes widened by held_ridge_px
  int held_count_ = 0;
  // Where a detection last confirmed each whisker: follicle and first direction.
  std::vector<Eigen::Vector2d> anchor_follicle_, anchor_direction_;
  // Each whisker's follicle on the first frame (associate_home_px).
  std::vector<Eigen::Vector2d> home_follicle_;
  // Each whisker's ridge contrast as its matched detections saw it (0: not yet seen).
  std::vector<double> contrast_;
};

}  // namespace sinew::rt
