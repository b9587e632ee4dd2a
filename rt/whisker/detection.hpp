#pragma once
/// Finding whiskers with no initialisation: the face (the dark region the whiskers grow from), the
/// whisker pad along its edge, and every whisker that leaves it, by following its ridge outwards.
/// Runs once at set-up (and may allocate); the per-frame tracking is rt::WhiskerTracker's.
///
/// The ridge measure is the one the tracker observes (ObservationMode::kDarkRidge): the contrast
/// (min(left, right) − centre) / max(left, right) across the ridge, in per cent of the local
/// backlight, with the sides 3 px from the centre along the direction of largest curvature of the
/// Gaussian-smoothed image. A graded backlight does not change it, and an edge (one side dark)
/// does not answer it, so the face's own outline and a dark pole's sides are not whiskers.
///
/// A whisker is accepted when its trace starts within the pad band (10 px) of the face, leaves the
/// face (reaches the band's edge, with min_clear_length_px beyond the band where its ridge measure
/// reads the face), is at least min_length_px long,
/// is as faint as a hair (max_contrast: a thin rod of the apparatus is not a whisker), and does
/// not run along a longer one.

#include <Eigen/Core>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "rt/image_view.hpp"

namespace sinew::rt {

/// The image border the face touches; kAuto takes the border with most dark pixels.
enum class FaceSide { kAuto, kLeft, kRight, kTop, kBottom };
const char* to_string(FaceSide side);
/// "auto", "left", "right", "top" or "bottom"; nullopt for anything else.
std::optional<FaceSide> face_side_from_string(const std::string& name);

struct WhiskerDetectionOptions {
  /// The detection's scales, thresholds and bridges that no user set (the smoothing, the ridge
  /// measure's side distance, the noise multiples of the thresholds, the pad band, the smoothing
  /// residual, ...) are fixed in detection.cpp (DetectionConstants), each with the measurement
  /// behind it; the thresholds follow the contrast map's measured noise. What is left here is
  /// what a user chooses (face side, shortest whisker, opt-in methods) or has been set by tests
  /// and tools to compare methods.
  FaceSide face = FaceSide::kAuto;
  /// A seed's ridge contrast, per cent of the backlight, > 0 (raised to 4× the contrast map's
  /// measured noise).
  double seed_contrast = 1.0;
  /// Tracing goes on while the contrast (per cent) is at least this, > 0 (raised to 2.5× the
  /// contrast map's measured noise).
  double follow_contrast = 0.5;
  /// A trace ends where it turns by more than this over 12 px, degrees, in (0, 180): a whisker
  /// (radius of curvature ≥ 25 px) turns less.
  double max_turn_deg = 30.0;
  /// Steps below follow_contrast bridged before a trace ends (a crossing, a faint stretch), ≥ 0.
  int max_gap_px = 12;
  /// ... while the trace heads towards the face, at least 4 px clear of a dark
  /// region (the contrast map's side samples off it), ≥ max_gap_px. Shared video, frame 0: the
  /// faint whisker beside the longest fades below follow_contrast over 15 px, 50-65 px from the
  /// face; its trace from the tip reaches the face with 16 (16-20 find the same whiskers). Nearer
  /// a dark region the longer bridge ran a trace on past a tip along the cheek.
  int max_gap_towards_face_px = 16;
  /// Within this distance of the face, where whiskers converge on the pad, a step whose ridge
  /// contrast falls below follow_contrast reads it again with each side the brighter of the
  /// samples 2 px and 3 px out (the gap before a neighbour 3-4 px away, where the sample
  /// 3 px out falls on the neighbour's shoulder), pixels, ≥ 0 (0: not read; the map is not
  /// computed; it costs detection 1.30x). Shared video, frame 0: the dense cluster's second
  /// whisker is traced to the face (6 whiskers found instead of 5); farther out, on the rendered
  /// pads' crossing pairs, it let traces run on along the other whisker (docs/tracker.md).
  double near_follow_px = 40.0;
  /// The trace a whisker is reported by: a least-squares polynomial of this degree in its arc
  /// length (0: the raw trace, re-centred step by step on a noisy ridge), fitted to the points
  /// farther than 11 px from the face's dark mask and extended along its
  /// tangent to the face's edge, [0, 6]. A trace the polynomial misses by more
  /// than 1.5 px is not one whisker and is dropped.
  int smoothing_degree = 3;
  /// Repair such traces instead: cut one at its worst point and fit it again while min_length_px
  /// remain; extend one that does not reach the face (cut there, or ending on a converging
  /// neighbour's ridge, or whose nearer end is a tip beside the cheek) along its tangent to the
  /// face over at most 25 px, on a ridge or a dark band, pixels; keep an extended one
  /// only when its follicle lies within 30 px of one a trace reached by itself. Off by
  /// default: on the shared video it finds more whiskers (frame 0: 6 against 5, the peer 7), and
  /// tracked with detection on every frame they lie on a ridge on 95.3-95.9 % of all
  /// whisker-frames (the video and its mirror images, brightest-sides measure) against 97.9-98.0 %
  /// by default, lost 50-60 against 18 (docs/tracker.md).
  bool repair_traces = false;
  /// A trace whose two ends both lie within 20 px (2 pad bands) of the face (a whisker whose tip
  /// lies over the cheek while its follicle end stops short of the pad, among its neighbours) takes
  /// as its follicle the end nearer the pad (the median of the follicles the other traces reached),
  /// extended along its tangent to the face as above. Otherwise the end nearer the face is the
  /// follicle, and a tip on the cheek was reported as one (shared video: on 12 of 30 sampled
  /// frames; with this, 3). On the video and its three mirror images: on a ridge 95.2 -> 95.6 %
  /// of all whisker-frames, follicle jumps 40 -> 36 (docs/tracker.md).
  bool orient_by_pad = true;
  /// Shortest whisker reported, pixels.
  double min_length_px = 40.0;
  /// A whisker leaves the face: a trace with less than this length farther than 11 px
  /// from the face (where smooth_trace can fit it; nearer, a side sample of
  /// the ridge measure falls on the face) is not reported, pixels, ≥ 0 (0: not tested; only with
  /// smoothing_degree > 0). Shared video, frame 35: a 34-point trace zig-zagging along the
  /// cheek's edge across the whiskers leaving it, never more than 14 px from the face; a whisker
  /// placed on it by the association was lost for the next 22 frames (docs/tracker.md).
  double min_clear_length_px = 15.0;
  /// The face and other objects: smoothed intensity below this fraction of the backlight, raised
  /// where the face stands out less than usual (dark_threshold), (0, 1).
  double dark_fraction = 0.35;
  /// Objects a whisker can touch (object_distance): lightly smoothed intensity below this
  /// fraction of the backlight (dark_threshold), in regions that come no nearer the
  /// face than 20 px, (0, 1).
  double object_fraction = 0.4;
  /// Keep the traces that were not accepted, with the reason (WhiskerDetection::rejected): for a
  /// user asking why a whisker was not found, and for an overlay.
  bool keep_rejected = false;

  std::optional<std::string> validate() const;
};

struct DetectedWhisker {
  std::vector<Eigen::Vector2d> points;  ///< the ridge centreline, follicle first, ~1 px apart
  Eigen::Vector2d follicle = Eigen::Vector2d::Zero();  ///< where the trace meets the face
  double length_px = 0.0;
  double contrast_percent = 0.0;  ///< median ridge contrast along the trace
};

/// A trace that is not a whisker, and why (WhiskerDetectionOptions::keep_rejected).
struct RejectedTrace {
  std::vector<Eigen::Vector2d> points;  ///< as traced (before smoothing), follicle end first
  std::string reason;  ///< "not smooth", "not at the face", "does not leave the face",
                       ///< "too dark", "too short", "runs along a longer whisker"
};

struct WhiskerDetection {
  std::vector<DetectedWhisker> whiskers;  ///< ordered along the face's edge
  FaceSide face = FaceSide::kAuto;        ///< the side used (resolved when kAuto was asked)
  double backlight = 0.0;      ///< the bright level (95th percentile of the frame smoothed by 4 px)
  double dark_level = 0.0;     ///< the face's level (its 1st percentile); see dark_threshold
  int seeds = 0;               ///< ridge points that were traced
  double noise_percent = 0.0;  ///< robust σ of the ridge contrast over the backlight
  double seed_contrast = 0.0;  ///< the seed and follow thresholds used, per cent
  double follow_contrast = 0.0;
  /// Distance of every pixel (row-major, the frame's width × height) to the nearest dark object
  /// that is not the face (a pole, a lick port: what a whisker can touch), pixels, capped at
  /// 255; empty when there is no such object. See rt/whisker/contact.hpp.
  std::vector<float> object_distance;
  std::vector<RejectedTrace> rejected;  ///< only with keep_rejected
  std::string error;                    ///< empty on success (bad options, no face found)
};

/// How much the thresholds in per cent of the backlight (detection's seed, follow and darkest
/// whisker contrasts) are scaled down on a video whose face
/// stands out less from the backlight than the reference (0.85 of it): min(1, ((backlight −
/// dark_level) / backlight) / 0.85), in [0.05, 1].
double contrast_scale(double backlight, double dark_level);

/// The grey level below which the frame smoothed by 4 px is dark (the face, a pole) for a
/// fraction of the backlight (dark_fraction, object_fraction): the fraction of the backlight while
/// the face stands out as usual (contrast_scale 1), else the fraction of the way from the face's
/// level up to the backlight (a lit face, a video of low contrast).
double dark_threshold(double fraction, double backlight, double dark_level);

/// The frame-sized maps and buffers a detection fills, kept from one detection to the next: a
/// session detecting again on every frame reuses them instead of allocating ~20 maps per frame
/// (their page faults were a visible share of its time). Sized by the first frame, re-sized when a
/// frame of another size comes. One per thread; it holds no result.
class WhiskerDetectionWorkspace {
 public:
  WhiskerDetectionWorkspace();
  ~WhiskerDetectionWorkspace();
  WhiskerDetectionWorkspace(WhiskerDetectionWorkspace&&) noexcept;
  WhiskerDetectionWorkspace& operator=(WhiskerDetectionWorkspace&&) noexcept;

  /// Detections run with it, and how many of them built the ridge maps a second time over the
  /// whole frame because a stage read them deeper inside a dark region than they are first built
  /// (the result is the same either way; this only counts the cost).
  int detections() const;
  int full_rebuilds() const;

  struct Buffers;  ///< defined in detection.cpp
  Buffers& buffers() { return *buffers_; }

 private:
  std::unique_ptr<Buffers> buffers_;
};

/// Detects the whiskers of one 8-bit grey frame.
WhiskerDetection detect_whiskers(const ImageView& frame, const WhiskerDetectionOptions& options);
/// The same, with the maps kept in (and reused from) a workspace: the same result.
WhiskerDetection detect_whiskers(const ImageView& frame, const WhiskerDetectionOptions& options,
                                 WhiskerDetectionWorkspace& workspace);

}  // namespace sinew::rt
