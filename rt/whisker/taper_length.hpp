#pragma once
/// A whisker's whole length, tip included, from how its drawn darkness falls along the part the
/// tracker follows. A whisker is a cone: its radius falls linearly from the follicle to a tip the
/// camera rarely sees (on the shared renderer's pads the tracker follows 0.6–0.95 of each
/// whisker). Where the whisker is thinner than the optics blur it, the darkness it removes across
/// its centreline (its "line mass": the profile's deficit below the backlight, integrated across)
/// is proportional to its width, so the line mass falls linearly along the whisker too; where
/// that line reaches zero is where the cone's radius would, and the tip is the tip-to-base radius
/// ratio short of it. The read-out's tapered cone (WhiskerPhysics) needs the whole length: over
/// the tracked length alone it reads the radius near a contact too small and E·I (∝ r⁴) with it
/// (docs/tracker.md, "Error bars").

#include <Eigen/Core>

#include "rt/image_view.hpp"

namespace sinew::rt {

struct TaperLength {
  /// The estimate, pixels along the centreline: the tracked length when not measured.
  double length_px = 0.0;
  /// The line mass fell along the whisker, and the estimate lies between the tracked length and
  /// twice it; else (a whisker too short to fit, neighbours or fur crossing its profile, a
  /// darkness that does not fall) the tracked length is kept.
  bool measured = false;
  double tracked_px = 0.0;  ///< the centreline's own length
  int samples = 0;          ///< profiles that entered the line fit
};

/// `centreline`: the whisker's nodes, follicle first (pixels). `tip_to_base` the ratio of the
/// tip's radius to the follicle's, in [0, 1).
TaperLength taper_length(const ImageView& frame, const Eigen::Matrix2Xd& centreline,
                         double tip_to_base);

}  // namespace sinew::rt
