#pragma once
/// Input checks of sinew-register that need the template: marker points far from it.
///
/// Template points (of attachments and landmarks) are in the template's frame and units. So are
/// the scan's points (attachment and landmark targets, ICP markers) when the case has attachments:
/// the attachments hold the template where it is. A point farther than kMaxMarkerDiagonals
/// bounding-box diagonals from the template's bounding box is then an input error (almost always a
/// file in another frame, another unit or a swapped column), reported before the slow tet meshing.
/// Without attachments (a free object, seed 003 §3.6) the scan may be anywhere: its points are not
/// checked. Template points nearer than the limit but still off the template mesh are caught
/// later, when they are embedded (register_case: 0.1 diagonal).

#include <Eigen/Core>
#include <string>

#include "offline/registration/registration_case.hpp"

namespace sinew::offline {

/// Largest distance of a marker point from the template's bounding box, in diagonals of that box.
/// An organ may deform a lot (the demo stretches a capsule 1.6x), but not by its own size again.
constexpr double kMaxMarkerDiagonals = 1.0;

/// Throws RegistrationInputError "<file>: <field>[i]: <kind> (x, y, z) is D <unit> from the
/// template's bounding box, k times its diagonal (the limit is 1); ..." for the first point farther
/// than kMaxMarkerDiagonals diagonals from the box [lo, hi] (or not finite): template points of
/// c.attachments and c.landmarks, then (with attachments) their targets and c.icp_markers.
/// unit: " mm", " m" or "".
void check_markers_near_template(const RegistrationCase& c, const Eigen::Vector3d& lo,
                                 const Eigen::Vector3d& hi, const std::string& unit);

}  // namespace sinew::offline
