// rt/whisker/detail/chessboard_distance.hpp against OpenCV's distance transform, pixel by pixel.
#include "rt/whisker/detail/chessboard_distance.hpp"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>
#include <random>

namespace sinew::rt::detail {
namespace {

// Pixels where chessboard_distance and cv::distanceTransform(DIST_C) (capped at 255) disagree.
int disagreements(const cv::Mat& mask) {
  cv::Mat expected, depth;
  cv::distanceTransform(mask, expected, cv::DIST_C, 3, CV_32F);
  chessboard_distance(mask, depth);
  int wrong = 0;
  for (int y = 0; y < mask.rows; ++y) {
    for (int x = 0; x < mask.cols; ++x) {
      wrong += depth.at<uchar>(y, x) != std::min(expected.at<float>(y, x), 255.0f);
    }
  }
  return wrong;
}

TEST(ChessboardDistance, AgreesWithOpenCvOnRandomMasks) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (const double zeros : {0.0005, 0.005, 0.05, 0.5}) {
    cv::Mat mask(97, 131, CV_8U);  // odd sizes; zero pixels near every border too
    for (int y = 0; y < mask.rows; ++y) {
      for (int x = 0; x < mask.cols; ++x) mask.at<uchar>(y, x) = unit(rng) < zeros ? 0 : 255;
    }
    EXPECT_EQ(disagreements(mask), 0) << "zero density " << zeros;
  }
}

TEST(ChessboardDistance, AgreesWithOpenCvInsideAFaceLikeBlobAndCapsAt255) {
  cv::Mat mask = cv::Mat::zeros(600, 640, CV_8U);
  cv::ellipse(mask, cv::Point(0, 300), cv::Size(400, 290), 0, 0, 360, 255, cv::FILLED);
  cv::circle(mask, cv::Point(500, 40), 6, 255, cv::FILLED);
  EXPECT_EQ(disagreements(mask), 0);
  cv::Mat depth;
  chessboard_distance(mask, depth);
  EXPECT_EQ(depth.at<uchar>(300, 0), 236);  // to the ellipse's outline along a diagonal
  EXPECT_EQ(depth.at<uchar>(40, 500), 5);   // the circle's centre, radius 6: 6 / sqrt(2) -> 5
  EXPECT_EQ(depth.at<uchar>(599, 639), 0);
  // Far from the only zero pixel: capped.
  cv::Mat far(300, 640, CV_8U, cv::Scalar(255));
  far.at<uchar>(0, 0) = 0;
  cv::Mat far_depth;
  chessboard_distance(far, far_depth);
  EXPECT_EQ(far_depth.at<uchar>(0, 200), 200);
  EXPECT_EQ(far_depth.at<uchar>(299, 639), 255);
  // The comparison can fail: one pixel off.
  depth.at<uchar>(40, 500) = 4;
  cv::Mat expected;
  cv::distanceTransform(mask, expected, cv::DIST_C, 3, CV_32F);
  EXPECT_NE(depth.at<uchar>(40, 500), expected.at<float>(40, 500));
}

TEST(ChessboardDistance, AMaskWithoutZerosIs255Everywhere) {
  const cv::Mat mask(20, 30, CV_8U, cv::Scalar(255));
  cv::Mat depth;
  chessboard_distance(mask, depth);
  EXPECT_EQ(cv::countNonZero(depth != 255), 0);
}

}  // namespace
}  // namespace sinew::rt::detail
