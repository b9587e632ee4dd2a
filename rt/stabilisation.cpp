#include "rt/stabilisation.hpp"

#include <Eigen/Dense>
#include <chrono>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <sstream>

namespace sinew::rt {

std::optional<std::string> StabiliserOptions::validate() const {
  std::ostringstream s;
  if (max_iterations < 1) {
    s << "max_iterations = " << max_iterations << " must be >= 1";
  } else if (!(epsilon > 0.0)) {
    s << "epsilon = " << epsilon << " must be > 0";
  } else if (!(mask_half_width_px >= 0.0)) {
    s << "mask_half_width_px = " << mask_half_width_px << " must be >= 0";
  } else if (!(min_correlation > 0.0 && min_correlation < 1.0)) {
    s << "min_correlation = " << min_correlation << " must be in (0, 1)";
  } else {
    return std::nullopt;
  }
  return s.str();
}

namespace {
cv::Mat half_float(const cv::Mat& grey) {
  cv::Mat small, f;
  cv::pyrDown(grey, small);
  small.convertTo(f, CV_32F);
  return f;
}
}  // namespace

Stabiliser::Stabiliser(const cv::Mat& reference, StabiliserOptions options)
    : options_(options),
      reference_small_(half_float(reference)),
      warp_small_(cv::Mat::eye(3, 3, CV_32F)) {}

StabiliserSummary Stabiliser::stabilise(const cv::Mat& frame, const Eigen::Matrix2Xd& object,
                                        cv::Mat& stabilised) {
  const auto t0 = std::chrono::steady_clock::now();
  StabiliserSummary summary;
  const cv::Mat frame_small = half_float(frame);
  // Mask the object where the previous homography puts it in this frame (ECC masks the input).
  cv::Mat mask(frame_small.size(), CV_8U, cv::Scalar(255));
  if (object.cols() >= 2) {
    std::vector<cv::Point> pts;
    for (Eigen::Index i = 0; i < object.cols(); ++i) {
      const cv::Matx33f H(warp_small_);
      const cv::Vec3f p = H * cv::Vec3f(float(object(0, i) / 2), float(object(1, i) / 2), 1.0f);
      pts.emplace_back(cvRound(p[0] / p[2]), cvRound(p[1] / p[2]));
    }
    cv::polylines(mask, pts, false, cv::Scalar(0),
                  std::max(1, int(std::lround(options_.mask_half_width_px))));
  }
  cv::Mat warp = warp_small_.clone();
  try {
    summary.correlation =
        cv::findTransformECC(reference_small_, frame_small, warp, cv::MOTION_HOMOGRAPHY,
                             cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS,
                                              options_.max_iterations, options_.epsilon),
                             mask, 5);
    summary.ok = summary.correlation >= options_.min_correlation;
  } catch (const cv::Exception&) {
    summary.ok = false;  // ECC did not converge: keep the previous homography
  }
  if (summary.ok) warp_small_ = warp;

  // Half-resolution H to full resolution: H = S⁻¹ H_small S with S = diag(1/2, 1/2, 1).
  cv::Matx33d Hs(warp_small_);
  const cv::Matx33d S(0.5, 0, 0, 0, 0.5, 0, 0, 0, 1), S_inv(2, 0, 0, 0, 2, 0, 0, 0, 1);
  const cv::Matx33d H = S_inv * Hs * S;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) summary.homography(r, c) = H(r, c) / H(2, 2);
  }
  // stabilised(x) = frame(H x): H maps reference → frame, hence WARP_INVERSE_MAP.
  cv::warpPerspective(frame, stabilised, cv::Mat(H), frame.size(),
                      cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_REPLICATE);
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return summary;
}

std::optional<Eigen::Vector2d> intersect_straight_poses(const Eigen::Matrix2Xd& pose_a,
                                                        const Eigen::Matrix2Xd& pose_b) {
  // Each line: centroid c and direction d (principal axis of the points).
  auto fit = [](const Eigen::Matrix2Xd& p, Eigen::Vector2d& c, Eigen::Vector2d& d) {
    c = p.rowwise().mean();
    const Eigen::Matrix2Xd q = p.colwise() - c;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(q * q.transpose());
    d = eig.eigenvectors().col(1);
  };
  if (pose_a.cols() < 2 || pose_b.cols() < 2) return std::nullopt;
  Eigen::Vector2d ca, da, cb, db;
  fit(pose_a, ca, da);
  fit(pose_b, cb, db);
  Eigen::Matrix2d A;
  A << da, -db;
  if (std::abs(A.determinant()) < 1e-6) return std::nullopt;
  const Eigen::Vector2d t = A.inverse() * (cb - ca);
  return Eigen::Vector2d(ca + t[0] * da);
}

}  // namespace sinew::rt
