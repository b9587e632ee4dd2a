// End to end, a free-flying organ (seed 003 §3.6) on real data: `sinew-register` registers the
// femur template of ../shared/data/femur_pair/ (femur_reference.stl, its 6 landmarks) to the
// target femur (a statistical-shape-model sample with the same topology): the target's 6
// landmarks and 150 points sampled on its surface as ICP markers, after the whole target was moved
// by 120° about an oblique axis and 300 mm. The case has no attachments, so the tool runs
// register_free with the tool's default ICP weight ramp. Checked: the mean symmetric surface
// distance (point to triangle, both directions) between the result and the moved target, the mean
// marker error, and (reported, not a criterion: closest-point markers let vertices slide along the
// surface) the vertex-to-vertex error, which the shared topology makes meaningful. Skips cleanly
// without ../shared.

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "offline/io/surface_mesh_io.hpp"
#include "offline/meshing/label_image.hpp"
#include "offline/registration/surface_distance.hpp"
#include "tests/support/run_tool.hpp"

namespace {

namespace fs = std::filesystem;
using sinew::testing::run_tool;

const std::string kTool = std::string(SINEW_BINARY_DIR) + "/tools/sinew-register";
const fs::path kData = fs::path(SINEW_SHARED_DIR) / "data" / "femur_pair";

std::vector<Eigen::Vector3d> read_landmarks(const fs::path& path) {
  std::ifstream in(path);
  const nlohmann::json j = nlohmann::json::parse(in);
  std::vector<Eigen::Vector3d> points;
  for (const auto& entry : j) {
    const auto& c = entry.at("coordinates");
    points.emplace_back(c.at(0).get<double>(), c.at(1).get<double>(), c.at(2).get<double>());
  }
  return points;
}

nlohmann::json as_json(const Eigen::Vector3d& p) {
  return {p.x(), p.y(), p.z()};
}

TEST(RegisterFemur, FreeFlyingFemurMovedFarMeetsTheTargetSurface) {
  if (!fs::exists(kData / "femur_reference.stl")) GTEST_SKIP() << "no " << kData;
  auto reference = sinew::offline::io::read_surface_mesh((kData / "femur_reference.stl").string());
  auto target = sinew::offline::io::read_surface_mesh((kData / "femur_target.stl").string());
  ASSERT_TRUE(reference.mesh && target.mesh) << reference.error << target.error;
  ASSERT_EQ(reference.mesh->vertices.rows(), target.mesh->vertices.rows());

  // The target moved: 120° about an oblique axis, then 300 mm.
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(120.0 * EIGEN_PI / 180.0, Eigen::Vector3d(1, -2, 3).normalized())
          .toRotationMatrix();
  const Eigen::Vector3d t = 300.0 * Eigen::Vector3d(2, 1, -2).normalized();
  sinew::offline::io::SurfaceMesh moved = *target.mesh;
  for (Eigen::Index v = 0; v < moved.vertices.rows(); ++v) {
    moved.vertices.row(v) = (R * target.mesh->vertices.row(v).transpose() + t).transpose();
  }

  const fs::path dir = fs::path(SINEW_BINARY_DIR) / "tests" / "tools" / "femur_case";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const auto template_landmarks = read_landmarks(kData / "femur_reference.json");
  const auto target_landmarks = read_landmarks(kData / "femur_target.json");
  ASSERT_EQ(template_landmarks.size(), 6u);
  ASSERT_EQ(target_landmarks.size(), 6u);
  nlohmann::json c;
  c["template"] = (kData / "femur_reference.stl").string();
  c["units"] = "mm";
  // A finer surface mesh than the tool's default (facets within 0.1% of the diagonal, 0.46 mm,
  // instead of 0.2%): ~5.7k tets. The plastic field's resolution near the surface limits the
  // result here: 0.96 mm mean symmetric distance with the default's 2.7k tets.
  c["mesh"] = {{"facet_distance_fraction", 0.001}};
  for (std::size_t k = 0; k < template_landmarks.size(); ++k) {
    c["landmarks"].push_back({{"template", as_json(template_landmarks[k])},
                              {"target", as_json(R * target_landmarks[k] + t)}});
  }
  // Well spread, as a user would place markers, without the 30 mm holes that 150 uniform random
  // points leave on a femur: farthest points among 20,000 area-weighted samples.
  for (const Eigen::Vector3d& p : sinew::offline::farthest_point_selection(
           sinew::offline::sample_surface_points(moved.vertices, moved.triangles, 20000, 2026),
           150)) {
    c["icp_markers"].push_back(as_json(p));
  }
  std::ofstream(dir / "case.json") << c.dump(1);
  ASSERT_TRUE(sinew::offline::io::write_obj((dir / "target_moved.obj").string(), moved));

  const auto r =
      run_tool(kTool + " --case " + (dir / "case.json").string() + " --out " +
                   (dir / "out").string() + " --truth " + (dir / "target_moved.obj").string(),
               dir);
  ASSERT_EQ(r.exit_status, 0) << r.out << r.err;
  std::cout << r.out;
  std::ifstream report_in(dir / "out" / "report.json");
  const nlohmann::json report = nlohmann::json::parse(report_in);
  EXPECT_EQ(report.at("mode"), "free");
  const double marker_mean = report.at("final").at("marker_error_mean").get<double>();
  const double marker_max = report.at("final").at("marker_error_max").get<double>();

  auto result =
      sinew::offline::io::read_surface_mesh((dir / "out" / "result_surface.obj").string());
  ASSERT_TRUE(result.mesh) << result.error;
  ASSERT_EQ(result.mesh->vertices.rows(), moved.vertices.rows());
  const auto forward = sinew::offline::vertex_to_surface_distances(*result.mesh, moved);
  const auto backward = sinew::offline::vertex_to_surface_distances(moved, *result.mesh);
  const double symmetric = 0.5 * (forward.mean + backward.mean);
  double vertex_sum = 0.0, vertex_max = 0.0;
  for (Eigen::Index v = 0; v < moved.vertices.rows(); ++v) {
    const double d = (result.mesh->vertices.row(v) - moved.vertices.row(v)).norm();
    vertex_sum += d;
    vertex_max = std::max(vertex_max, d);
  }
  std::printf(
      "femur: marker error mean %.3f max %.3f mm; surface distance result->target mean %.3f max "
      "%.3f, target->result mean %.3f max %.3f, symmetric mean %.3f mm; vertex-to-vertex mean "
      "%.3f max %.3f mm\n",
      marker_mean, marker_max, forward.mean, forward.max, backward.mean, backward.max, symmetric,
      vertex_sum / static_cast<double>(moved.vertices.rows()), vertex_max);
  // Issue acceptance: markers ≤ 0.3 mm on average and the surface within 0.5 mm mean symmetric
  // distance. With the tool's ICP weight ramp and the exact uniform-strain initial fit: markers
  // 0.016 mm, surface 0.39 mm (the same with the target not moved); with its 10 point-to-plane
  // ICP iterations as well, 0.018 mm and 0.335 mm. The paper's plain ICP stage gave 0.57 mm here:
  // it meets the markers at once on closest points taken from the landmark-stage shape.
  EXPECT_LE(marker_mean, 0.3);
  EXPECT_LE(symmetric, 0.5);
}

}  // namespace
