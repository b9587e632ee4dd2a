#pragma once
/// Image observations along the beam normal (seed 000 §4: "we sample every beam segment and then
/// search for multiple observations in the direction of the beam normal"). Instead of a full-frame
/// edge map, each search reads a 1-D intensity profile of a few dozen pixels across the model and
/// finds the strongest local responses with sub-pixel localisation (parabola through 3 samples).
///
/// Modes: kEdge finds intensity steps (each boundary of a thick object); kDarkLine / kBrightLine
/// find the centre of a thin line with a centre-surround response in grey levels; kDarkRidge finds
/// a faint dark ridge (a whisker on a backlight) by its contrast relative to the local background:
/// (min(left, right) − centre) / max(left, right) in per cent, which a graded backlight does not
/// change and an edge (one side dark) does not answer. kEdgeMap is the
/// seed's own observation, for comparisons: the image is a binary edge map of the current frame
/// (e.g. cv::Canny), and each search takes the edge pixels nearest the model along the normal.

#include <Eigen/Core>

#include "rt/image_view.hpp"

namespace sinew::rt {

enum class ObservationMode { kEdge, kDarkLine, kBrightLine, kEdgeMap, kDarkRidge };

/// For kEdge: which way intensity steps across the object's boundary. kAuto decides on the first
/// frame (is the object darker or brighter than its surroundings along the initial polyline?);
/// kAny accepts both, and so also accepts the far boundary and clutter of the opposite polarity.
enum class EdgePolarity { kAuto, kAny, kDarkObject, kBrightObject };

struct Candidate {
  float offset = 0.0f;  ///< position along the search normal relative to its centre, pixels
  /// Response: grey levels per pixel (edges), grey levels (lines), per cent of the local
  /// background (ridges).
  float strength = 0.0f;
};

/// Image points where a search may not take a candidate: a caller's veto (e.g. the ridges other
/// whiskers hold this frame, so that a whisker whose fit slid onto a neighbour's ridge can be
/// fitted again on its own). Called from the per-frame path: must not allocate.
class CandidateExclusion {
 public:
  virtual ~CandidateExclusion() = default;
  virtual bool excluded(const Eigen::Vector2d& point) const noexcept = 0;
};

struct ProfileSearch {
  ObservationMode mode = ObservationMode::kEdge;
  /// kEdge: +1 when intensity must increase along the search direction, −1 decrease, 0 either.
  int expected_sign = 0;
  int range_px = 8;           ///< search offsets −range..range (1 px steps)
  int max_candidates = 3;     ///< strongest local maxima kept
  float min_strength = 8.0f;  ///< weaker responses are ignored
  int line_surround_px = 3;   ///< line modes: distance of the surround samples from the centre
  int band_px = 1;            ///< profile averaged over ±band_px pixels along the tangent
  /// kDarkRidge: no response where the brighter side is darker than this (grey levels): inside
  /// the face or another dark object, texture would otherwise read as large relative contrast.
  float min_background = 0.0f;
  /// kDarkRidge: the depth below the mean of both sides, bounded by 4× the depth below the darker
  /// side, instead of the latter (for lines where the background is curved, see
  /// TrackerOptions::start_mean_surround_px).
  bool ridge_mean_surround = false;
  /// kDarkRidge (lines without ridge_mean_surround): the sub-pixel position of a candidate from the
  /// profile's own darkness ([1 2 1]-smoothed, the vertex of a parabola through the three
  /// samples around the response's peak) instead of from the ridge response, whose side samples
  /// add their noise to the position (see TrackerOptions::ridge_position_from_profile).
  bool ridge_position_from_profile = false;

  /// Profile samples needed beyond ±range_px: the central difference reads ±1 more around each
  /// response and the local-maximum test one response more (edges); lines read ±(surround + 1).
  int margin() const { return mode == ObservationMode::kEdge ? 2 : line_surround_px + 2; }
  /// Scratch floats search_profile() needs (profile and response).
  int scratch_size() const { return 2 * (2 * (range_px + line_surround_px + 2) + 1); }
};

/// Reads the intensity profile I(centre + k·normal) for k = first … first + count − 1 (1 px steps),
/// each averaged over ±band_px pixels along the tangent (noise ÷ √(2·band + 1)), bilinear. A
/// profile point with a sample outside the image is NaN. No allocation.
void sample_profile(const ImageView& image, const Eigen::Vector2d& centre,
                    const Eigen::Vector2d& normal, int first, int count, int band_px,
                    float* profile);

/// Asks the memory system for the pixels that sample_profile(image, centre, normal, first, count,
/// ·) reads (a software prefetch of each pixel row the line crosses; results do not change). A
/// camera frame arrives outside the cache: prefetching a search line or two ahead overlaps those
/// misses with the sampling (measured: about a tenth of the tracker's per-frame time). No
/// allocation.
void prefetch_profile(const ImageView& image, const Eigen::Vector2d& centre,
                      const Eigen::Vector2d& normal, int first, int count);

/// Finds the candidates of one search line on a profile read by sample_profile: profile[origin + k]
/// is the sample at offset k, and must exist for |k| ≤ range_px + margin(). Offsets are searched
/// over |k| ≤ range_px and reported as k + δ − shift (δ the sub-pixel peak, shift the line centre's
/// offset from the profile's origin, |shift| ≤ 0.5). `response` holds as many floats as the
/// profile. Writes up to max_candidates candidates, strongest first; returns how many.
int find_candidates(const float* profile, int origin, float shift, const ProfileSearch& search,
                    float* response, Candidate* out);

/// kEdgeMap: walks centre + s·normal, |s| ≤ range_px, in half-pixel steps over a binary edge map
/// (nonzero = edge); a step hits when a pixel of its 2x2 bilinear support is an edge (so a 1 px
/// diagonal edge cannot slip between two steps), and each run of hits gives one candidate at its
/// centre with strength 255. Writes up to max_candidates candidates, nearest the centre first.
int search_edge_map(const ImageView& edges, const Eigen::Vector2d& centre,
                    const Eigen::Vector2d& normal, int range_px, int max_candidates,
                    Candidate* out);

/// Searches along centre + s·normal (sample_profile, then find_candidates). Writes up to
/// max_candidates candidates, strongest first, into `out` and returns how many. `scratch` holds
/// scratch_size() floats. Pixels outside the image produce no candidates. No allocation.
int search_profile(const ImageView& image, const Eigen::Vector2d& centre,
                   const Eigen::Vector2d& normal, const ProfileSearch& search, float* scratch,
                   Candidate* out);

}  // namespace sinew::rt
