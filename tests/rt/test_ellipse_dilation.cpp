// rt/whisker/detail/ellipse_dilation.hpp against OpenCV's own dilation, pixel by pixel.
#include "rt/whisker/detail/ellipse_dilation.hpp"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>
#include <random>

namespace sinew::rt::detail {
namespace {

// Pixels where EllipseDilation and cv::dilate with the same ellipse disagree.
int disagreements(const cv::Mat& mask, int reach) {
  const cv::Mat kernel =
      cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * reach + 1, 2 * reach + 1));
  cv::Mat expected;
  cv::dilate(mask, expected, kernel);
  const EllipseDilation d(mask, reach);
  int wrong = 0;
  for (int y = 0; y < mask.rows; ++y) {
    for (int x = 0; x < mask.cols; ++x) wrong += d.covers(x, y) != (expected.at<uchar>(y, x) != 0);
  }
  return wrong;
}

TEST(EllipseDilation, CoversWhatOpenCvsDilationCoversOnRandomMasks) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (const int reach : {0, 1, 2, 3, 5, 8, 13, 21, 30}) {
    for (const double density : {0.0005, 0.005, 0.05}) {
      cv::Mat mask(97, 131, CV_8U);  // odd sizes; set pixels near every border too
      for (int y = 0; y < mask.rows; ++y) {
        for (int x = 0; x < mask.cols; ++x) mask.at<uchar>(y, x) = unit(rng) < density ? 255 : 0;
      }
      EXPECT_EQ(disagreements(mask, reach), 0) << "reach " << reach << ", density " << density;
    }
  }
}

TEST(EllipseDilation, CoversWhatOpenCvsDilationCoversAroundAFaceLikeBlob) {
  // A face-like region on the left border, as whisker detection dilates it (reach 21).
  cv::Mat mask = cv::Mat::zeros(240, 320, CV_8U);
  cv::ellipse(mask, cv::Point(0, 120), cv::Size(70, 100), 0, 0, 360, 255, cv::FILLED);
  cv::circle(mask, cv::Point(200, 40), 3, 255, cv::FILLED);  // and a small object
  for (const int reach : {4, 21, 40}) EXPECT_EQ(disagreements(mask, reach), 0) << reach;
  // The check can fail: a kernel one pixel smaller covers less.
  const EllipseDilation smaller(mask, 20);
  const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(43, 43));
  cv::Mat expected;
  cv::dilate(mask, expected, kernel);
  int wrong = 0;
  for (int y = 0; y < mask.rows; ++y) {
    for (int x = 0; x < mask.cols; ++x) {
      wrong += smaller.covers(x, y) != (expected.at<uchar>(y, x) != 0);
    }
  }
  EXPECT_GT(wrong, 100);
}

TEST(EllipseDilation, AnEmptyMaskCoversNothing) {
  const cv::Mat mask = cv::Mat::zeros(30, 40, CV_8U);
  const EllipseDilation d(mask, 5);
  for (int y = 0; y < mask.rows; ++y) {
    for (int x = 0; x < mask.cols; ++x) EXPECT_FALSE(d.covers(x, y));
  }
}

}  // namespace
}  // namespace sinew::rt::detail
