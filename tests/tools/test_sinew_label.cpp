// Tests of sinew-label (tools/label) and the label-image pieces under it (offline/meshing/
// label_image, offline/io/volume_image_io): a synthetic NIfTI label image of an ellipsoid with a
// known world placement (flipped x axis, offset, 2 mm voxels) gives a sub-voxel surface on the
// analytic ellipsoid, mirrored on request; markers lie on it and are well spread; the slice
// pictures show the surface on the mask outline. Bad input: one line, exit 2. And, with
// ../shared, the case end to end: the right gluteus medius mirrored and meshed as the
// template, 200 ICP markers on the left one, sinew-register (a free object), and cross-section
// PNGs of the result over the CT.

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "offline/io/surface_mesh_io.hpp"
#include "offline/io/volume_image_io.hpp"
#include "tests/support/run_tool.hpp"

namespace {

namespace fs = std::filesystem;
using sinew::testing::run_tool;

const std::string kLabel = std::string(SINEW_BINARY_DIR) + "/tools/sinew-label";
const std::string kRegister = std::string(SINEW_BINARY_DIR) + "/tools/sinew-register";
const Eigen::Vector3d kCentre(10, -5, 40), kAxes(30, 20, 15);

// |r − 1|·(smallest semi-axis), r the ellipsoidal radius: about the distance to the ellipsoid.
double off_ellipsoid(const Eigen::Vector3d& p) {
  return std::abs((p - kCentre).cwiseQuotient(kAxes).norm() - 1.0) * kAxes.minCoeff();
}

fs::path make_dir(const std::string& name) {
  const fs::path dir = fs::path(SINEW_BINARY_DIR) / "tests" / "tools" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// Label 3 inside the ellipsoid, 0 elsewhere; i runs towards −x (a flipped axis).
fs::path write_ellipsoid(const fs::path& dir) {
  sinew::offline::io::VolumeImage image;
  image.size = Eigen::Vector3i(40, 30, 25);
  image.index_to_world.topLeftCorner<3, 3>() = Eigen::Vector3d(-2, 2, 2).asDiagonal();
  image.index_to_world.topRightCorner<3, 1>() = Eigen::Vector3d(50, -35, 15);
  image.values.assign(static_cast<std::size_t>(image.size.prod()), 0.0f);
  for (int k = 0; k < image.size.z(); ++k)
    for (int j = 0; j < image.size.y(); ++j)
      for (int i = 0; i < image.size.x(); ++i) {
        const Eigen::Vector3d p = image.world(Eigen::Vector3d(i, j, k));
        if ((p - kCentre).cwiseQuotient(kAxes).norm() <= 1.0)
          image.values[static_cast<std::size_t>(image.index(i, j, k))] = 3.0f;
      }
  const fs::path path = dir / "ellipsoid.nii.gz";
  EXPECT_TRUE(sinew::offline::io::write_nifti(path.string(), image));
  return path;
}

std::vector<Eigen::Vector3d> read_csv(const fs::path& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);  // header
  std::vector<Eigen::Vector3d> points;
  while (std::getline(in, line)) {
    for (char& c : line) c = c == ',' ? ' ' : c;
    std::istringstream s(line);
    Eigen::Vector3d p;
    s >> p.x() >> p.y() >> p.z();
    points.push_back(p);
  }
  return points;
}

TEST(SinewLabel, EllipsoidSurfaceMarkersAndSlices) {
  const fs::path dir = make_dir("label_ellipsoid");
  const fs::path image = write_ellipsoid(dir);
  auto r = run_tool(
      kLabel + " surface " + image.string() + " --label 3 --out " + (dir / "s.obj").string(), dir);
  ASSERT_EQ(r.exit_status, 0) << r.err;
  auto surface = sinew::offline::io::read_surface_mesh((dir / "s.obj").string());
  ASSERT_TRUE(surface.mesh) << surface.error;
  double sum = 0.0, worst = 0.0;
  for (Eigen::Index v = 0; v < surface.mesh->vertices.rows(); ++v) {
    const double d = off_ellipsoid(surface.mesh->vertices.row(v).transpose());
    sum += d;
    worst = std::max(worst, d);
  }
  const double mean = sum / static_cast<double>(surface.mesh->vertices.rows());
  std::printf(
      "ellipsoid surface: %ld vertices, off the ellipsoid mean %.3f max %.3f mm (voxel 2 mm)\n",
      static_cast<long>(surface.mesh->vertices.rows()), mean, worst);
  EXPECT_LT(mean, 0.6);   // sub-voxel
  EXPECT_LT(worst, 2.0);  // within one voxel everywhere

  // Mirrored across x = 0: the centre moves to x = −10.
  r = run_tool(kLabel + " surface " + image.string() + " --label 3 --mirror-x 0 --out " +
                   (dir / "m.obj").string(),
               dir);
  ASSERT_EQ(r.exit_status, 0) << r.err;
  auto mirrored = sinew::offline::io::read_surface_mesh((dir / "m.obj").string());
  ASSERT_TRUE(mirrored.mesh);
  EXPECT_NEAR(mirrored.mesh->vertices.col(0).mean(), -kCentre.x(), 1.0);

  r = run_tool(kLabel + " markers " + image.string() + " --label 3 --count 60 --out " +
                   (dir / "markers.csv").string(),
               dir);
  ASSERT_EQ(r.exit_status, 0) << r.err;
  const auto markers = read_csv(dir / "markers.csv");
  ASSERT_EQ(markers.size(), 60u);
  double closest_pair = INFINITY, worst_marker = 0.0;
  for (std::size_t a = 0; a < markers.size(); ++a) {
    worst_marker = std::max(worst_marker, off_ellipsoid(markers[a]));
    for (std::size_t b = a + 1; b < markers.size(); ++b)
      closest_pair = std::min(closest_pair, (markers[a] - markers[b]).norm());
  }
  EXPECT_LT(worst_marker, 2.0);
  EXPECT_GT(closest_pair, 4.0);  // well spread (uniform random points would have pairs < 1 mm)

  r = run_tool(kLabel + " slices " + image.string() + " --mask " + image.string() +
                   " --label 3 --window 0 3 --count 3 --surface " + (dir / "s.obj").string() +
                   " --out " + (dir / "slices").string(),
               dir);
  ASSERT_EQ(r.exit_status, 0) << r.err;
  int pictures = 0;
  for (const auto& entry : fs::directory_iterator(dir / "slices"))
    pictures += entry.path().extension() == ".png";
  EXPECT_EQ(pictures, 3);
  // Every slice line reports the cross-section's distance to the mask outline: under a voxel.
  std::istringstream lines(r.out);
  int reported = 0;
  for (std::string line; std::getline(lines, line);) {
    const auto at = line.find("outline mean ");
    if (at == std::string::npos) continue;
    ++reported;
    EXPECT_LT(std::stod(line.substr(at + 13)), 2.0) << line;
  }
  EXPECT_EQ(reported, 3);
}

TEST(SinewLabel, BadInputIsOneLineAndExit2) {
  const fs::path dir = make_dir("label_bad");
  const fs::path image = write_ellipsoid(dir);
  auto r = run_tool(kLabel + " markers " + (dir / "missing.nii.gz").string() + " --count 5 --out " +
                        (dir / "m.csv").string(),
                    dir);
  EXPECT_EQ(r.exit_status, 2);
  EXPECT_NE(r.err.find("missing.nii.gz: cannot open"), std::string::npos) << r.err;
  r = run_tool(
      kLabel + " surface " + image.string() + " --label 7 --out " + (dir / "s.obj").string(), dir);
  EXPECT_EQ(r.exit_status, 2);
  EXPECT_NE(r.err.find("label 7 occurs in no voxel"), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1);
  EXPECT_FALSE(fs::exists(dir / "s.obj"));
}

TEST(SinewLabel, GluteusMediusCaseEndToEnd) {
  const fs::path data = fs::path(SINEW_SHARED_DIR) / "data" / "totalsegmentator_ct";
  if (!fs::exists(data / "gluteus_medius_left.nii.gz")) GTEST_SKIP() << "no " << data;
  const fs::path dir = make_dir("gluteus_case");
  const std::string right = (data / "gluteus_medius_right.nii.gz").string();
  const std::string left = (data / "gluteus_medius_left.nii.gz").string();
  auto r = run_tool("cd " + dir.string() + " && " + kLabel + " surface " + right +
                        " --mirror-x-centre --out template.obj",
                    dir);
  ASSERT_EQ(r.exit_status, 0) << r.err;
  r = run_tool("cd " + dir.string() + " && " + kLabel + " markers " + left +
                   " --count 200 --out markers.csv",
               dir);
  ASSERT_EQ(r.exit_status, 0) << r.err;
  r = run_tool("cd " + dir.string() + " && " + kLabel + " surface " + left + " --out target.obj",
               dir);
  ASSERT_EQ(r.exit_status, 0) << r.err;
  // The case names its scan: sinew-register writes the cross-sections itself (OUTDIR/slices).
  nlohmann::json c = {
      {"template", "template.obj"},
      {"units", "mm"},
      {"icp_markers", "markers.csv"},
      {"scan_image",
       {{"image", (data / "example_ct.nii.gz").string()}, {"mask", left}, {"slices", 3}}}};
  std::ofstream(dir / "case.json") << c.dump(1);
  r = run_tool(
      "cd " + dir.string() + " && " + kRegister + " --case case.json --out out --truth target.obj",
      dir);
  ASSERT_EQ(r.exit_status, 0) << r.out << r.err;
  std::cout << r.out;
  std::ifstream report_in(dir / "out" / "report.json");
  const nlohmann::json report = nlohmann::json::parse(report_in);
  EXPECT_EQ(report.at("mode"), "free");
  const double to_truth = report.at("truth").at("result_to_truth_mean").get<double>();
  const double from_truth = report.at("truth").at("truth_to_result_mean").get<double>();
  std::printf("gluteus medius: result to the left muscle's surface mean %.2f mm, back %.2f mm\n",
              to_truth, from_truth);
  EXPECT_LT(0.5 * (to_truth + from_truth), 1.5);  // half a 3 mm voxel
  // The tool's own cross-sections: 3 PNGs, each cut within two voxels of the mask's outline.
  ASSERT_EQ(report.at("slices").size(), 3u) << report.dump(1);
  for (const auto& slice : report.at("slices")) {
    EXPECT_TRUE(fs::exists(dir / slice.at("file").get<std::string>())) << slice;  // rel. to dir
    EXPECT_LT(slice.at("mean_distance_to_mask_outline").get<double>(), 6.0) << slice;
  }
  r = run_tool("cd " + dir.string() + " && " + kLabel + " slices " +
                   (data / "example_ct.nii.gz").string() + " --mask " + left +
                   " --surface out/result_surface.obj --count 4 --out slices",
               dir);
  ASSERT_EQ(r.exit_status, 0) << r.err;
  std::cout << r.out;
  int pictures = 0;
  for (const auto& entry : fs::directory_iterator(dir / "slices"))
    pictures += entry.path().extension() == ".png";
  EXPECT_EQ(pictures, 4);
}

}  // namespace
