// The moving-camera helpers: the ground point of two straight poses, and the ECC stabiliser
// recovering a known homography of a textured image.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "rt/stabilisation.hpp"

namespace sinew::rt {
namespace {

TEST(Stabilisation, GroundPointIsTheIntersectionOfTwoPoses) {
  const Eigen::Vector2d ground(120.0, 640.0);
  auto pose = [&](double angle) {
    Eigen::Matrix2Xd p(2, 6);
    for (int i = 0; i < 6; ++i) {
      p.col(i) = ground + (40.0 + 50.0 * i) * Eigen::Vector2d(std::cos(angle), -std::sin(angle));
    }
    return p;
  };
  const auto g = intersect_straight_poses(pose(0.9), pose(1.6));
  ASSERT_TRUE(g.has_value());
  EXPECT_LT((*g - ground).norm(), 1e-6);
  EXPECT_FALSE(intersect_straight_poses(pose(0.9), pose(0.9)).has_value()) << "parallel poses";
}

TEST(Stabilisation, RecoversAKnownHomography) {
  // A smooth textured reference and a frame seen through H (reference → frame).
  cv::Mat reference(480, 640, CV_8UC1);
  cv::RNG rng(5);
  cv::Mat noise(60, 80, CV_32F);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 255);
  cv::Mat big;
  cv::resize(noise, big, reference.size(), 0, 0, cv::INTER_CUBIC);
  cv::GaussianBlur(big, big, cv::Size(0, 0), 3.0);
  big.convertTo(reference, CV_8U);
  const double a = 0.03;
  const cv::Matx33d H(std::cos(a), -std::sin(a), 12.0, std::sin(a), std::cos(a), -7.0, 2e-5, -1e-5,
                      1.0);
  cv::Mat frame;  // frame(H x) = reference(x)
  cv::warpPerspective(reference, frame, cv::Mat(H), reference.size(), cv::INTER_LINEAR,
                      cv::BORDER_REFLECT);
  Stabiliser stabiliser(reference);
  cv::Mat stabilised;
  StabiliserSummary s;
  for (int k = 0; k < 3; ++k) s = stabiliser.stabilise(frame, Eigen::Matrix2Xd(), stabilised);
  ASSERT_TRUE(s.ok);
  // Compare where both homographies send points inside the image.
  double worst = 0.0;
  for (double x : {100.0, 320.0, 540.0}) {
    for (double y : {80.0, 240.0, 400.0}) {
      const cv::Vec3d p = H * cv::Vec3d(x, y, 1.0);
      const Eigen::Vector3d q = s.homography * Eigen::Vector3d(x, y, 1.0);
      worst = std::max(worst, std::hypot(p[0] / p[2] - q.x() / q.z(), p[1] / p[2] - q.y() / q.z()));
    }
  }
  EXPECT_LT(worst, 0.3) << "pixels";
}

}  // namespace
}  // namespace sinew::rt
