#pragma once
/// Contact between a tracked whisker and an object in the image (a pole, a lick port): the
/// whisker touches where its centreline comes within `touch_px` of the object, from a
/// distance-to-objects map (WhiskerDetection::object_distance); the contact point is the closest
/// approach along the first such stretch from the follicle. Its arc length is the contact point a
/// lab reports (and where the contact load acts). No allocation.

#include <Eigen/Core>

#include "rt/tracker.hpp"

namespace sinew::rt {

struct WhiskerContact {
  bool touching = false;
  double arc_length_px = 0.0;  ///< from the follicle along the centreline, when touching
  Eigen::Vector2d point = Eigen::Vector2d::Zero();
  double distance_px = 0.0;  ///< the centreline's least distance to an object
};

/// distance: row-major width × height map (pixels to the nearest object; empty: no object).
/// touch_px: the centreline counts as touching within this distance (the whisker's half-width
/// and the object mask's blur), > 0. skip_px: the first this many pixels from the follicle are
/// not looked at (the face's own shadow), ≥ 0.
WhiskerContact find_contact(const Tracker& whisker, const float* distance, int width, int height,
                            double touch_px = 3.5, double skip_px = 10.0) noexcept;

/// The direction away from the nearest object at p: the distance map's gradient (central
/// differences over ±1 px of its bilinear interpolation), not normalised; zero off the map.
Eigen::Vector2d away_from_objects(const float* distance, int width, int height,
                                  const Eigen::Vector2d& p) noexcept;

}  // namespace sinew::rt
