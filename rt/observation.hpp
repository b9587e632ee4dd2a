#pragma once
/// Image observations along the beam normal (seed 000 §4: "we sample every beam segment and then
/// search for multiple observations in the direction of the beam normal"). Instead of a full-frame
/// edge map, each search reads a 1-D intensity profile of a few dozen pixels across the model and
/// finds the strongest local responses with sub-pixel localisation (parabola through 3 samples).
///
/// Modes: kEdge finds intensity steps (each boundary of a thick object); kDarkLine / kBrightLine
/// find the centre of a thin line (whiskers) with a centre-surround response.

#include <Eigen/Core>

#include "rt/image_view.hpp"

namespace sinew::rt {

enum class ObservationMode { kEdge, kDarkLine, kBrightLine };

/// For kEdge: which way intensity steps across the object's boundary. kAuto decides on the first
/// frame (is the object darker or brighter than its surroundings along the initial polyline?);
/// kAny accepts both, and so also accepts the far boundary and clutter of the opposite polarity.
enum class EdgePolarity { kAuto, kAny, kDarkObject, kBrightObject };

struct Candidate {
  float offset = 0.0f;    ///< position along the search normal relative to its centre, pixels
  float strength = 0.0f;  ///< response (grey levels per pixel for edges, grey levels for lines)
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

  /// Scratch floats search() needs (profile and response).
  int scratch_size() const { return 2 * (2 * (range_px + line_surround_px + 2) + 1); }
};

/// Searches along centre + s·normal. Writes up to max_candidates candidates, strongest first, into
/// `out` and returns how many. `scratch` holds scratch_size() floats. Pixels outside the image
/// produce no candidates. No allocation.
int search_profile(const ImageView& image, const Eigen::Vector2d& centre,
                   const Eigen::Vector2d& normal, const ProfileSearch& search, float* scratch,
                   Candidate* out);

}  // namespace sinew::rt
