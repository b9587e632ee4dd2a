// offline/registration/marker_checks: marker points far from the template are input errors
// (another frame, another unit, swapped columns), named by file, field and index.
#include "offline/registration/marker_checks.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

namespace {

using sinew::offline::check_markers_near_template;
using sinew::offline::RegistrationCase;
using sinew::offline::RegistrationInputError;

// A template box [0, 100] x [0, 40] x [0, 30] mm (diagonal 111.8 mm); two attachments and an
// ICP marker on it.
RegistrationCase box_case() {
  RegistrationCase c;
  c.attachments.template_points.resize(2, 3);
  c.attachments.template_points << 0, 0, 0, 100, 40, 30;
  c.attachments.target_points = c.attachments.template_points;
  c.attachments.source = c.attachments.template_source = "case.json";
  c.icp_markers.resize(1, 3);
  c.icp_markers << 50, 20, 15;
  c.icp_markers_source = "markers.csv";
  return c;
}

const Eigen::Vector3d kLo(0, 0, 0), kHi(100, 40, 30);

std::string message(const RegistrationCase& c) {
  try {
    check_markers_near_template(c, kLo, kHi, " mm");
  } catch (const RegistrationInputError& e) {
    return e.what();
  }
  return "";
}

TEST(MarkerChecks, PointsWithinADiagonalOfTheBoxPass) {
  RegistrationCase c = box_case();
  EXPECT_EQ(message(c), "");
  c.icp_markers << 100 + 111.0, 20, 15;  // 111 mm beyond the box: just inside the limit
  EXPECT_EQ(message(c), "");
}

TEST(MarkerChecks, AFarMarkerIsNamedByFileFieldIndexAndDistance) {
  RegistrationCase c = box_case();
  c.icp_markers << 50, 20, 15 + 1000.0;  // metres read as millimetres, say
  const std::string m = message(c);
  EXPECT_EQ(m.rfind("markers.csv: icp_markers[0]: marker (50, 20, 1015) is 985 mm from the "
                    "template's bounding box, 8.81 times its diagonal",
                    0),
            0u)
      << m;
  c = box_case();
  c.attachments.target_points(1, 0) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(message(c).find("case.json: attachments[1]: target (nan"), std::string::npos)
      << message(c);
  c = box_case();
  c.attachments.template_points(0, 2) = -500.0;
  EXPECT_NE(message(c).find("attachments[0]: template point"), std::string::npos) << message(c);
}

TEST(MarkerChecks, AFreeObjectsScanMayBeAnywhereButItsTemplatePointsMayNot) {
  RegistrationCase c = box_case();
  c.landmarks = c.attachments;
  c.landmarks.target_points.array() += 5000.0;  // the person's scan in its own frame
  c.attachments = {};
  c.icp_markers.array() += 5000.0;
  EXPECT_EQ(message(c), "");
  c.landmarks.template_points(1, 1) = 900.0;
  EXPECT_NE(message(c).find("landmarks[1]: template point"), std::string::npos) << message(c);
}

}  // namespace
