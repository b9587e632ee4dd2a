#include "offline/registration/marker_checks.hpp"

#include <fmt/core.h>

#include "offline/registration/registration_case.hpp"

namespace sinew::offline {
namespace {

/// Euclidean distance from p to the box [lo, hi] (0 inside).
double distance_to_box(const Eigen::Vector3d& p, const Eigen::Vector3d& lo,
                       const Eigen::Vector3d& hi) {
  return (lo - p).cwiseMax(p - hi).cwiseMax(0.0).norm();
}

void check_points(const Eigen::MatrixXd& points, const std::string& source,
                  const std::string& field, const char* kind, const Eigen::Vector3d& lo,
                  const Eigen::Vector3d& hi, const std::string& unit) {
  const double diagonal = (hi - lo).norm();
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    const Eigen::Vector3d p = points.row(i).transpose();
    const double d = distance_to_box(p, lo, hi);
    if (d <= kMaxMarkerDiagonals * diagonal) continue;  // false for NaN too
    throw RegistrationInputError(fmt::format(
        "{}: {}[{}]: {} ({:.6g}, {:.6g}, {:.6g}) is {:.4g}{} from the template's bounding box, "
        "{:.3g} times its diagonal (the limit is {:g}); is it in the template's frame and units?",
        source, field, i, kind, p.x(), p.y(), p.z(), d, unit, d / diagonal, kMaxMarkerDiagonals));
  }
}

}  // namespace

void check_markers_near_template(const RegistrationCase& c, const Eigen::Vector3d& lo,
                                 const Eigen::Vector3d& hi, const std::string& unit) {
  check_points(c.attachments.template_points, c.attachments.template_source, "attachments",
               "template point", lo, hi, unit);
  check_points(c.landmarks.template_points, c.landmarks.template_source, "landmarks",
               "template point", lo, hi, unit);
  if (c.attachments.size() == 0) return;  // a free object: the scan's frame is fitted
  check_points(c.attachments.target_points, c.attachments.source, "attachments", "target", lo, hi,
               unit);
  check_points(c.landmarks.target_points, c.landmarks.source, "landmarks", "target", lo, hi, unit);
  check_points(c.icp_markers, c.icp_markers_source, "icp_markers", "marker", lo, hi, unit);
}

}  // namespace sinew::offline
