#include "tools/label/slice_pictures.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace sinew::tools {

namespace fs = std::filesystem;

std::vector<SlicePicture> write_slice_pictures(const offline::io::VolumeImage& image,
                                               const offline::io::VolumeImage* mask,
                                               const offline::io::SurfaceMesh& S,
                                               const std::string& out_dir,
                                               const SlicePictureOptions& options) {
  std::vector<SlicePicture> pictures;
  // Surface vertices in voxel index coordinates.
  const Eigen::Matrix4d to_index = image.index_to_world.inverse();
  Eigen::MatrixXd ijk(S.vertices.rows(), 3);
  for (Eigen::Index v = 0; v < S.vertices.rows(); ++v)
    ijk.row(v) = (to_index.topLeftCorner<3, 3>() * S.vertices.row(v).transpose() +
                  to_index.topRightCorner<3, 1>())
                     .transpose();
  const double k_min = ijk.col(2).minCoeff(), k_max = ijk.col(2).maxCoeff();
  fs::create_directories(out_dir);
  for (int s = 0; s < options.count; ++s) {
    const double kk = k_min + (k_max - k_min) * (s + 1.0) / (options.count + 1.0);
    const int k = std::clamp(static_cast<int>(std::lround(kk)), 0, image.size.z() - 1);
    cv::Mat gray(image.size.y(), image.size.x(), CV_8UC1);
    cv::Mat inside(image.size.y(), image.size.x(), CV_8UC1, cv::Scalar(0));
    for (int j = 0; j < image.size.y(); ++j)
      for (int i = 0; i < image.size.x(); ++i) {
        const double v =
            (image.at(i, j, k) - options.window_low) / (options.window_high - options.window_low);
        gray.at<unsigned char>(j, i) = static_cast<unsigned char>(std::clamp(v, 0.0, 1.0) * 255);
        if (mask) {
          const float m = mask->at(i, j, k);
          inside.at<unsigned char>(j, i) =
              (options.label < 0 ? m > 0.5f : std::lround(m) == options.label) ? 255 : 0;
        }
      }
    cv::Mat picture;
    cv::resize(gray, picture, cv::Size(), options.zoom, options.zoom, cv::INTER_NEAREST);
    cv::cvtColor(picture, picture, cv::COLOR_GRAY2BGR);
    std::vector<std::vector<cv::Point>> contours;
    if (mask) {
      cv::Mat big;
      cv::resize(inside, big, cv::Size(), options.zoom, options.zoom, cv::INTER_NEAREST);
      cv::findContours(big, contours, cv::RETR_LIST, cv::CHAIN_APPROX_NONE);
      cv::drawContours(picture, contours, -1, cv::Scalar(0, 200, 0), 1);
    }
    // The surface's cross-section with the plane k = const (voxel centres at integer indices).
    double distance_sum = 0.0;
    int distance_count = 0;
    for (Eigen::Index f = 0; f < S.triangles.rows(); ++f) {
      std::vector<Eigen::Vector2d> cut;
      for (int e = 0; e < 3; ++e) {
        const Eigen::Vector3d a = ijk.row(S.triangles(f, e)).transpose();
        const Eigen::Vector3d b = ijk.row(S.triangles(f, (e + 1) % 3)).transpose();
        if ((a.z() - k) * (b.z() - k) < 0.0) {
          const double t = (k - a.z()) / (b.z() - a.z());
          cut.push_back((a + t * (b - a)).head<2>());
        }
      }
      if (cut.size() != 2) continue;
      auto pixel = [&](const Eigen::Vector2d& p) {
        return cv::Point(static_cast<int>(std::lround((p.x() + 0.5) * options.zoom - 0.5)),
                         static_cast<int>(std::lround((p.y() + 0.5) * options.zoom - 0.5)));
      };
      cv::line(picture, pixel(cut[0]), pixel(cut[1]), cv::Scalar(0, 0, 255), 1, cv::LINE_AA);
      if (!contours.empty()) {
        const Eigen::Vector2d mid = 0.5 * (cut[0] + cut[1]);
        const cv::Point2f q(static_cast<float>((mid.x() + 0.5) * options.zoom - 0.5),
                            static_cast<float>((mid.y() + 0.5) * options.zoom - 0.5));
        double best = INFINITY;
        for (const auto& c : contours)
          best = std::min(best, std::abs(cv::pointPolygonTest(c, q, true)));
        distance_sum += best / options.zoom * image.spacing().x();
        ++distance_count;
      }
    }
    // Radiological display: the patient's left on the right, anterior up (NIfTI world is RAS+).
    const bool flip_i = image.index_to_world(0, 0) > 0.0, flip_j = image.index_to_world(1, 1) > 0.0;
    if (flip_i || flip_j) cv::flip(picture, picture, flip_i && flip_j ? -1 : flip_i ? 1 : 0);
    char name[64];
    std::snprintf(name, sizeof(name), "k = %d: surface red, mask green", k);
    cv::putText(picture, name, cv::Point(8, 20), cv::FONT_HERSHEY_SIMPLEX, 0.5,
                cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
    std::snprintf(name, sizeof(name), "slice_k%03d.png", k);
    const fs::path file = fs::path(out_dir) / name;
    cv::imwrite(file.string(), picture);
    SlicePicture result;
    result.file = file.string();
    result.k = k;
    if (distance_count > 0) result.mean_distance = distance_sum / distance_count;
    pictures.push_back(result);
  }
  return pictures;
}

}  // namespace sinew::tools
