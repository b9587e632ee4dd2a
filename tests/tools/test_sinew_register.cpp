// sinew-register end to end. (1) A closed box surface (written as OBJ by the test) with its x = 0
// end attached at rest; the truth is the box stretched 1.3x along x (a uniform plastic stretch
// Fp = diag(1.3, 1, 1), exactly reachable and stress-free); ICP markers are sampled on the truth's
// surface. The tool must meet the markers, put every template surface vertex near the truth, and
// give the same shape for the case in millimetres and in metres (normalisation). (2) Bad inputs:
// one line naming the file (and line:column or field), exit status 2, no result files. (3) The
// Botsch–Sorkine bar (../shared/data/botsch_benchmark) with its fixed and handle regions as
// attachments under the .def transform. (4) The demo case (--make-demo-case: a capsule stretched
// and bent by a known deformation) registered with --truth: the result surface is near the truth.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "offline/io/surface_mesh_io.hpp"
#include "offline/meshing/surface_closest_point.hpp"
#include "offline/registration/surface_distance.hpp"
#include "tests/support/run_tool.hpp"
#include "tests/support/tet_mesh_fixtures.hpp"
#include "tools/register/demo_case.hpp"

namespace {

namespace fs = std::filesystem;
using sinew::offline::io::SurfaceMesh;
using sinew::testing::read_text;
using sinew::testing::run_tool;
using sinew::testing::scratch_dir;
using sinew::testing::write_text;

const std::string kTool = std::string(SINEW_BINARY_DIR) + "/tools/sinew-register";

using sinew::tools::box_surface;

nlohmann::json xyz(const Eigen::Vector3d& p) {
  return {p.x(), p.y(), p.z()};
}

// The stretch case: box of 4 x 1 x 1 units (unit = 10 mm or 0.01 m), attached at x = 0. The
// truth φ(x, y, z) = (x + 0.3x²/4, y, z) stretches it from 1 at the attached end to 1.6 at the free
// end (1.3x longer overall): ∇φ = diag(1 + 0.15x, 1, 1) is a symmetric plastic field, so the
// truth is reachable and stress-free, but not by the constant initial fit alone.
Eigen::Vector3d truth(const Eigen::Vector3d& p, double unit) {
  sinew::tools::AxialStretchBend phi;  // σ(t) = 4(t + 0.3t²) units with t = x / 4 units
  phi.free_length = 4 * unit;
  phi.stretch = 0.3;
  return phi(p);
}

struct StretchCase {
  SurfaceMesh surface;
  nlohmann::json json;
  double unit = 1.0;
};

StretchCase stretch_case(double unit, const std::string& units) {
  StretchCase c;
  c.unit = unit;
  c.surface = box_surface(Eigen::Vector3d(4, 1, 1) * unit, Eigen::Vector3i(8, 2, 2));
  nlohmann::json attachments = nlohmann::json::array();
  for (int j = 0; j <= 2; ++j) {
    for (int k = 0; k <= 2; ++k) {
      const Eigen::Vector3d p(0.0, 0.5 * j * unit, 0.5 * k * unit);
      attachments.push_back({{"template", xyz(p)}, {"target", xyz(p)}});
    }
  }
  // ICP markers on the truth's surface, away from the attached face.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  nlohmann::json markers = nlohmann::json::array();
  for (int m = 0; m < 80; ++m) {
    Eigen::Vector3d p(0.3 + 3.7 * uniform(rng), uniform(rng), uniform(rng));
    const int face = m % 5;  // four sides and the far end
    if (face < 4) {
      p[1 + face / 2] = face % 2;
    } else {
      p.x() = 4;
    }
    markers.push_back(xyz(truth(p * unit, unit)));
  }
  c.json = {{"template", "box.obj"},
            {"units", units},
            {"mesh",
             {{"cell_size_fraction", 0.12},
              {"facet_distance_fraction", 0.02},
              {"protect_sharp_features", true}}},
            {"attachments", attachments},
            {"icp_markers", markers}};
  return c;
}

struct Obj {
  std::vector<Eigen::Vector3d> vertices;
  int faces = 0;
};

Obj read_obj(const fs::path& path) {
  Obj obj;
  std::istringstream in(read_text(path));
  for (std::string line; std::getline(in, line);) {
    std::istringstream s(line);
    std::string tag;
    s >> tag;
    if (tag == "v") {
      Eigen::Vector3d p;
      s >> p.x() >> p.y() >> p.z();
      obj.vertices.push_back(p);
    } else if (tag == "f") {
      ++obj.faces;
    }
  }
  return obj;
}

struct RunOutcome {
  sinew::testing::ToolResult result;
  nlohmann::json report;
  Obj surface;
  double seconds = 0.0;
};

RunOutcome run_case(const fs::path& dir, const std::string& extra = "") {
  RunOutcome o;
  const auto start = std::chrono::steady_clock::now();
  o.result = run_tool(kTool + " --case " + (dir / "case.json").string() + " --out " +
                          (dir / "out").string() + extra,
                      dir);
  o.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (fs::exists(dir / "out" / "report.json"))
    o.report = nlohmann::json::parse(read_text(dir / "out" / "report.json"));
  if (fs::exists(dir / "out" / "result_surface.obj"))
    o.surface = read_obj(dir / "out" / "result_surface.obj");
  return o;
}

TEST(SinewRegister, StretchedBoxFromIcpMarkersInMillimetresAndMetres) {
  std::vector<RunOutcome> runs;
  std::vector<StretchCase> cases;
  for (const auto& [unit, units] :
       std::vector<std::pair<double, std::string>>{{10.0, "mm"}, {0.01, "m"}}) {
    SCOPED_TRACE(units);
    const auto dir = scratch_dir("sinew_register_stretch_" + units);
    StretchCase c = stretch_case(unit, units);
    ASSERT_TRUE(sinew::offline::io::write_obj((dir / "box.obj").string(), c.surface));
    write_text(dir / "case.json", c.json.dump(1));
    RunOutcome o = run_case(dir);
    ASSERT_EQ(o.result.exit_status, 0) << o.result.err << o.result.out;
    std::cout << o.result.out;

    // Outputs exist and parse.
    ASSERT_TRUE(fs::exists(dir / "out" / "result.vtu"));
    const std::string vtu = read_text(dir / "out" / "result.vtu");
    EXPECT_NE(vtu.find("Name=\"Fp\" NumberOfComponents=\"9\""), std::string::npos);
    EXPECT_NE(vtu.find("Name=\"principal_stretches\" NumberOfComponents=\"3\""), std::string::npos);
    EXPECT_NE(vtu.find("</VTKFile>"), std::string::npos);
    EXPECT_NE(vtu.find("<PointData Scalars=\"distance_to_nearest_marker\">"), std::string::npos);
    ASSERT_TRUE(o.report.is_object());
    // 80 markers spread over the four sides and the far end: no part of the surface is far from
    // all of them.
    EXPECT_LT(o.report["coverage"]["uncovered_area_fraction"].get<double>(), 0.02);
    EXPECT_LT(o.report["coverage"]["weakly_pinned_area_fraction"].get<double>(), 0.05);
    EXPECT_NE(vtu.find("Name=\"marker_pinning\""), std::string::npos);
    EXPECT_EQ(o.report["length_unit"], units);
    EXPECT_GT(o.report["iterations"].size(), 0u);
    EXPECT_GT(o.report["inputs"]["tets"].get<int>(), 0);
    EXPECT_TRUE(o.report["inputs"]["mesher"].contains("min_dihedral_degrees"));
    EXPECT_EQ(o.report["inputs"]["icp_markers"].get<int>(), 80);
    for (const auto& it : o.report["iterations"]) {
      for (const char* key : {"stage", "iteration", "objective", "step", "marker_error_mean",
                              "marker_error_max", "seconds"})
        EXPECT_TRUE(it.contains(key)) << key;
    }

    // Markers met: the final max marker error is small against the size (diagonal ≈ 4.24 units).
    const double size = std::sqrt(18.0) * unit;
    const double final_max = o.report["final"]["marker_error_max"].get<double>();
    EXPECT_EQ(o.report["final"]["stage"], "icp");
    EXPECT_LT(final_max, 0.01 * size);

    // Same vertices and triangles as the template; vertices near the truth (1.3x along x).
    ASSERT_EQ(o.surface.vertices.size(), static_cast<std::size_t>(c.surface.vertices.rows()));
    EXPECT_EQ(o.surface.faces, c.surface.triangles.rows());
    // ICP markers carry no correspondence: the vertices may slide along the truth's surface (on
    // a box any monotone stretch profile of the same length has the same surface). So: every
    // vertex on the truth's surface, the two end faces' vertices on the end planes, and the
    // vertex-to-vertex error reported.
    const Eigen::Vector3d hi = Eigen::Vector3d(5.2, 1, 1) * unit;
    double worst = 0.0, off_surface = 0.0, ends = 0.0;
    for (std::size_t i = 0; i < o.surface.vertices.size(); ++i) {
      const Eigen::Vector3d p = c.surface.vertices.row(static_cast<Eigen::Index>(i)).transpose();
      const Eigen::Vector3d q = o.surface.vertices[i];
      worst = std::max(worst, (q - truth(p, unit)).norm());
      // Distance to the box [0, hi]'s surface: outside, the excess; inside, the nearest face.
      const Eigen::Vector3d outside = (q - hi).cwiseMax(-q).cwiseMax(0.0);
      const double distance = outside.norm() > 0 ? outside.norm() : q.cwiseMin(hi - q).minCoeff();
      off_surface = std::max(off_surface, distance);
      if (p.x() == 0.0) ends = std::max(ends, std::abs(q.x()));
      if (p.x() == 4 * unit) ends = std::max(ends, std::abs(q.x() - hi.x()));
    }
    std::cout << units << ": final marker error max " << final_max << " " << units
              << "; surface vertices: off the truth's surface max " << off_surface
              << ", end faces off their planes max " << ends << ", vertex-to-vertex max " << worst
              << " " << units << " (" << 100 * worst / size << "% of the diagonal); "
              << o.report["inputs"]["tets"] << " tets, " << o.seconds << " s\n";
    EXPECT_LT(off_surface, 0.01 * size);
    EXPECT_LT(ends, 0.01 * size);
    EXPECT_LT(worst, 0.1 * size);
    EXPECT_LT(o.seconds, 120.0);
    runs.push_back(std::move(o));
    cases.push_back(std::move(c));
  }
  // Same shape up to the unit factor (1000).
  ASSERT_EQ(runs.size(), 2u);
  ASSERT_EQ(runs[0].surface.vertices.size(), runs[1].surface.vertices.size());
  double difference = 0.0;
  for (std::size_t i = 0; i < runs[0].surface.vertices.size(); ++i)
    difference = std::max(
        difference, (runs[0].surface.vertices[i] - 1000.0 * runs[1].surface.vertices[i]).norm());
  std::cout << "mm vs m: largest vertex difference " << difference << " mm\n";
  EXPECT_LT(difference, 1e-3 * std::sqrt(18.0) * 10.0);
}

// The same box with markers on its attached half only (x < 2 units): its free half is shaped by
// the smoothness term alone, and the coverage report says so and where.
TEST(SinewRegister, CoverageReportsTheHalfWithoutMarkers) {
  const double unit = 10.0;
  const auto dir = scratch_dir("sinew_register_coverage");
  StretchCase c = stretch_case(unit, "mm");
  nlohmann::json near_half = nlohmann::json::array();
  for (const auto& m : c.json["icp_markers"])
    if (m[0].get<double>() < 2 * unit) near_half.push_back(m);
  ASSERT_GE(near_half.size(), 20u);
  c.json["icp_markers"] = near_half;
  ASSERT_TRUE(sinew::offline::io::write_obj((dir / "box.obj").string(), c.surface));
  write_text(dir / "case.json", c.json.dump(1));
  const RunOutcome o = run_case(dir);
  ASSERT_EQ(o.result.exit_status, 0) << o.result.err << o.result.out;
  const nlohmann::json& coverage = o.report["coverage"];
  std::cout << near_half.size() << " markers on the attached half; coverage " << coverage.dump()
            << "\n";
  // The far half is about half the area; the band within 1.5 spacings of the markers is covered.
  EXPECT_GT(coverage["uncovered_area_fraction"].get<double>(), 0.15);
  EXPECT_LT(coverage["uncovered_area_fraction"].get<double>(), 0.6);
  // The farthest point is on the far end (x ≥ 4 units before the stretch).
  EXPECT_GT(coverage["farthest_point"][0].get<double>(), 4 * unit);
  EXPECT_GT(coverage["max_distance_spacings"].get<double>(), 1.5);
  EXPECT_GT(coverage["weakly_pinned_area_fraction"].get<double>(), 0.15);
  EXPECT_GT(coverage["weakest_point"][0].get<double>(), 3 * unit);
  EXPECT_NE(o.result.out.find("The shape there comes from the smoothness term"), std::string::npos)
      << o.result.out;
}

// --- bad inputs

std::string obj_text(const SurfaceMesh& mesh) {
  std::ostringstream s;
  s.precision(17);
  for (Eigen::Index v = 0; v < mesh.vertices.rows(); ++v)
    s << "v " << mesh.vertices(v, 0) << " " << mesh.vertices(v, 1) << " " << mesh.vertices(v, 2)
      << "\n";
  for (Eigen::Index f = 0; f < mesh.triangles.rows(); ++f)
    s << "f " << mesh.triangles(f, 0) + 1 << " " << mesh.triangles(f, 1) + 1 << " "
      << mesh.triangles(f, 2) + 1 << "\n";
  return s.str();
}

// Medit .mesh text: vertices on lines 5.., the Tetrahedra count on line 5 + #V + 2 and tet t
// (0-based) on line 5 + #V + 3 + t.
std::string medit_text(const Eigen::MatrixXd& vertices, const Eigen::MatrixXi& tets) {
  std::ostringstream s;
  s.precision(17);
  s << "MeshVersionFormatted 1\nDimension 3\nVertices\n" << vertices.rows() << "\n";
  for (Eigen::Index v = 0; v < vertices.rows(); ++v)
    s << vertices(v, 0) << " " << vertices(v, 1) << " " << vertices(v, 2) << " 0\n";
  s << "Tetrahedra\n" << tets.rows() << "\n";
  for (Eigen::Index t = 0; t < tets.rows(); ++t)
    s << tets(t, 0) + 1 << " " << tets(t, 1) + 1 << " " << tets(t, 2) + 1 << " " << tets(t, 3) + 1
      << " 0\n";
  s << "End\n";
  return s.str();
}

// The 4 x 1 x 1 box of the bad-input cases as a tet mesh: 4 cubes, 24 right-handed Kuhn tets.
sinew::testing::TetMesh box_tets() {
  return sinew::testing::make_box_mesh(4, 1, 1);
}

struct BadCase {
  std::string name;
  std::string case_text;                                   // case.json ("" = no case file)
  std::vector<std::pair<std::string, std::string>> files;  // other files in the folder
  std::string expected;                                    // piece of the message
  std::string names_file;                                  // the file the message must name
};

TEST(SinewRegister, BadInputGivesOneLineErrorAndNoOutput) {
  const SurfaceMesh box = box_surface(Eigen::Vector3d(4, 1, 1), Eigen::Vector3i(4, 1, 1));
  nlohmann::json good = {
      {"template", "box.obj"},
      {"mesh", {{"cell_size_fraction", 0.2}}},
      {"attachments", {{{"template", {0, 0.5, 0.5}}, {"target", {0, 0.5, 0.5}}}}},
      {"icp_markers", {{4.5, 0.5, 0.5}}}};
  auto with = [&](auto edit) {
    nlohmann::json j = good;
    edit(j);
    return j.dump(1);
  };
  SurfaceMesh open = box;
  open.triangles.conservativeResize(open.triangles.rows() - 1, 3);
  const std::string open_obj = obj_text(open);
  // Two boxes overlapping in one file: each closed and manifold, together self-intersecting.
  SurfaceMesh crossed = box;
  {
    const Eigen::Index nv = box.vertices.rows(), nf = box.triangles.rows();
    crossed.vertices.conservativeResize(2 * nv, 3);
    crossed.vertices.bottomRows(nv) = box.vertices.rowwise() + Eigen::RowVector3d(2, 0.5, 0.25);
    crossed.triangles.conservativeResize(2 * nf, 3);
    crossed.triangles.bottomRows(nf) = box.triangles.array() + static_cast<int>(nv);
  }
  // The template with a NaN on the third vertex line.
  std::string nan_obj = obj_text(box);
  {
    const auto third = nan_obj.find("\nv ", nan_obj.find("\nv ") + 1) + 1;
    nan_obj.replace(third, nan_obj.find('\n', third) - third, "v 4 nan 0");
  }
  // Tet-mesh templates (Medit .mesh): 20 vertices (vertex v, 0-based, on line 5 + v), 24 tets
  // (tet t on line 27 + t).
  const sinew::testing::TetMesh tets = box_tets();
  Eigen::MatrixXi mixed = tets.tets;
  for (Eigen::Index t = 5; t < mixed.rows(); t += 7) std::swap(mixed(t, 0), mixed(t, 1));  // 3
  Eigen::MatrixXi flat(tets.tets.rows() + 1, 4);  // + a tet on the bottom face of the first cube
  flat << tets.tets, Eigen::RowVector4i(0, 1, 5, 6);
  Eigen::MatrixXd inf_vertex = tets.rest_positions;
  inf_vertex(7, 2) = std::numeric_limits<double>::infinity();
  // JSON has no NaN or infinity: an infinite inline coordinate is a number that overflows.
  std::string inf_inline = good.dump(1);
  const std::size_t inf_at = inf_inline.find("4.5");
  inf_inline.replace(inf_at, 3, "1e999");
  const std::string inf_line =
      std::to_string(1 + std::count(inf_inline.begin(), inf_inline.begin() + inf_at, '\n'));

  const std::vector<BadCase> cases = {
      {"missing_case", "", {}, "cannot open", "case.json"},
      {"malformed_json",
       "{\n \"template\": \"box.obj\",\n \"attachments\": [ }\n",
       {},
       "case.json:3:",
       "case.json"},
      {"unknown_key",
       with([](auto& j) { j["attachmnets"] = j["attachments"]; }),
       {},
       "unknown key 'attachmnets'",
       "case.json"},
      // No attachments is a free object (§3.6), which needs 3 landmarks or ICP markers; 1 here.
      {"free_object_with_one_marker",
       with([](auto& j) { j.erase("attachments"); }),
       {},
       "free object (seed 003 §3.6), which needs at least 3 landmarks or 3 ICP markers",
       "case.json"},
      {"bad_units", with([](auto& j) { j["units"] = "cm"; }), {}, "units", "case.json"},
      {"bad_point",
       with([](auto& j) {
         j["icp_markers"][0] = {1, 2};
       }),
       {},
       "icp_markers[0]",
       "case.json"},
      {"bad_weight",
       with([](auto& j) {
         j["weights"] = {{"alpha", -1}};
       }),
       {},
       "weights.alpha",
       "case.json"},
      {"bad_mesh_option",
       with([](auto& j) { j["mesh"]["cell_size_fraction"] = 2.0; }),
       {},
       "cell_size_fraction",
       "case.json"},
      {"marker_file_bad_line",
       with([](auto& j) { j["icp_markers"] = "markers.csv"; }),
       {{"markers.csv", "x,y,z\n1,2,3\n4,5\n"}},
       "markers.csv:3:",
       "markers.csv"},
      {"missing_marker_file",
       with([](auto& j) { j["landmarks"] = "nope.csv"; }),
       {},
       "cannot open",
       "nope.csv"},
      {"missing_template",
       with([](auto& j) { j["template"] = "nope.obj"; }),
       {},
       "nope.obj",
       "nope.obj"},
      {"open_template",
       with([](auto& j) { j["template"] = "open.obj"; }),
       {{"open.obj", open_obj}},
       "cannot tet-mesh the template surface: the surface is open: 3 edges belong to one face "
       "only, e.g. edge (",
       "open.obj"},
      {"self_intersecting_template",
       with([](auto& j) { j["template"] = "crossed.obj"; }),
       {{"crossed.obj", obj_text(crossed)}},
       "cannot tet-mesh the template surface: the surface intersects itself: faces ",
       "crossed.obj"},
      {"nan_in_template_surface",
       with([](auto& j) { j["template"] = "nan.obj"; }),
       {{"nan.obj", nan_obj}},
       "nan.obj:3: vertex has a non-finite coordinate (4 nan 0)",
       "nan.obj"},
      {"inf_in_template_tet_mesh",
       with([](auto& j) {
         j["template"] = "inf.mesh";
         j.erase("mesh");
       }),
       {{"inf.mesh", medit_text(inf_vertex, tets.tets)}},
       "inf.mesh:12: vertex 8 has a non-finite coordinate (2 1 inf)",
       "inf.mesh"},
      {"mixed_orientation_tets",
       with([](auto& j) {
         j["template"] = "mixed.mesh";
         j.erase("mesh");
       }),
       {{"mixed.mesh", medit_text(tets.rest_positions, mixed)}},
       "mixed.mesh:32: element 6 is inverted (signed volume -0.166667) while 21 of the 24 tets "
       "are positive: mixed orientation",
       "mixed.mesh"},
      {"degenerate_tet",
       with([](auto& j) {
         j["template"] = "flat.mesh";
         j.erase("mesh");
       }),
       {{"flat.mesh", medit_text(tets.rest_positions, flat)}},
       "flat.mesh:51: element 25 is degenerate (signed volume 0",
       "flat.mesh"},
      {"inf_in_inline_marker",
       inf_inline,
       {},
       "invalid JSON: number overflow parsing '1e999' (not a finite double)",
       "case.json:" + inf_line + ":"},
      {"nan_in_marker_file",
       with([](auto& j) { j["icp_markers"] = "markers.csv"; }),
       {{"markers.csv", "x,y,z\n1,0.5,0.5\n2,nan,0.5\n"}},
       "markers.csv:3: field 2 (y) is not finite: 'nan'",
       "markers.csv"},
      {"inf_in_landmark_file",
       with([](auto& j) { j["landmarks"] = "landmarks.csv"; }),
       {{"landmarks.csv", "1,0.5,0.5,1,0.5,0.5\n2,0.5,0.5,2,0.5,1e999\n"}},
       "landmarks.csv:2: field 6 (z) is not finite: '1e999'",
       "landmarks.csv"},
      {"far_icp_marker",
       with([](auto& j) {
         j["icp_markers"].push_back({400, 0.5, 0.5});
       }),
       {},
       "case.json: icp_markers[1]: marker (400, 0.5, 0.5) is 396 from the template's bounding "
       "box, 93.3 times its diagonal (the limit is 1); is it in the template's frame and units?",
       "case.json"},
      {"far_marker_in_file",
       with([](auto& j) { j["icp_markers"] = "markers.csv"; }),
       {{"markers.csv", "x,y,z\n1,0.5,0.5\n2,0.5,0.5\n2000,500,500\n"}},
       "markers.csv: icp_markers[2]: marker (2000, 500, 500) is 2117 from",
       "markers.csv"},
      {"far_attachment_target",
       with([](auto& j) {
         j["attachments"][0]["target"] = {0, 0.5, -20};
       }),
       {},
       "case.json: attachments[0]: target (0, 0.5, -20) is 20 from the template's bounding box",
       "case.json"},
      {"far_landmark_template_point",
       with([](auto& j) {
         j["landmarks"] = {{{"template", {2, 0.5, 0.5}}, {"target", {2, 0.5, 0.5}}},
                           {{"template", {2, -9, 0.5}}, {"target", {2, 0.5, 0.5}}}};
       }),
       {},
       "case.json: landmarks[1]: template point (2, -9, 0.5) is 9 from",
       "case.json"},
      {"empty_icp_marker_list",
       with([](auto& j) { j["icp_markers"] = nlohmann::json::array(); }),
       {},
       "case.json:16:17: icp_markers is empty",
       "case.json"},
      {"empty_attachment_list",
       with([](auto& j) { j["attachments"] = nlohmann::json::array(); }),
       {},
       "case.json:2:17: attachments is empty",
       "case.json"},
      {"empty_marker_file",
       with([](auto& j) { j["icp_markers"] = "markers.csv"; }),
       {{"markers.csv", "x,y,z\n"}},
       "markers.csv: no points",
       "markers.csv"},
      {"empty_landmark_file",
       with([](auto& j) { j["landmarks"] = "landmarks.json"; }),
       {{"landmarks.json", "[]"}},
       "no pairs",
       "landmarks.json"},
      {"template_is_a_folder",
       with([](auto& j) { j["template"] = "folder.obj"; }),
       {{"folder.obj/", ""}},
       "folder.obj: cannot read: is a directory",
       "folder.obj"},
      {"marker_file_is_a_folder",
       with([](auto& j) { j["icp_markers"] = "markers.csv"; }),
       {{"markers.csv/", ""}},
       "markers.csv: cannot read: is a directory",
       "markers.csv"},
      {"unknown_nested_key",
       with([](auto& j) {
         j["weights"] = {{"alhpa", 1e5}};
       }),
       {},
       "case.json:28:12: unknown key 'alhpa' in weights (expected one of: alpha, beta, "
       "attachment_stiffness, icp_weight_ramp, icp_point_to_plane_iterations, icp_stage_landmarks, "
       "landmark_stage)",
       "case.json"},
      {"scan_image_missing",
       with([](auto& j) {
         j["scan_image"] = {{"image", "missing.nii.gz"}};
       }),
       {},
       "missing.nii.gz: cannot open",
       "missing.nii.gz"},
      {"scan_image_without_image",
       with([](auto& j) {
         j["scan_image"] = {{"slices", 3}};
       }),
       {},
       "case.json:26:16: scan_image needs \"image\"",
       "case.json"},
      {"ramp_factor_out_of_range",
       with([](auto& j) {
         j["weights"] = {{"icp_weight_ramp", {0.01, 2.0}}};
       }),
       {},
       "case.json:30:4: weights.icp_weight_ramp[1] = 2 must be in (0, 1]",
       "case.json"},
      {"point_to_plane_iterations_negative",
       with([](auto& j) {
         j["weights"] = {{"icp_point_to_plane_iterations", -1}};
       }),
       {},
       "case.json:28:36: weights.icp_point_to_plane_iterations = -1 must be in [0, 100000]",
       "case.json"},
      {"far_attachment",
       with([](auto& j) {
         j["attachments"][0]["template"] = {1000, 0.5, 0.5};
       }),
       {},
       "case.json: attachments[0]: template point (1000, 0.5, 0.5) is 996 from the template's "
       "bounding box",
       "case.json"},
      // Within a diagonal of the box but 1.3 outside the tet mesh: caught when embedded (after
      // meshing, which these options keep to about a second).
      {"attachment_outside_mesh",
       with([](auto& j) {
         j["mesh"] = {{"cell_size_fraction", 0.12},
                      {"facet_distance_fraction", 0.02},
                      {"protect_sharp_features", true}};
         j["attachments"][0]["template"] = {0, 0.5, -1.3};
       }),
       {},
       "case.json: attachments[0]: template point is 1.3 from the template mesh (30.6% of its "
       "diagonal)",
       "case.json"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.name);
    const auto dir = scratch_dir("sinew_register_bad_" + c.name);
    ASSERT_TRUE(sinew::offline::io::write_obj((dir / "box.obj").string(), box));
    if (!c.case_text.empty()) write_text(dir / "case.json", c.case_text);
    for (const auto& [name, text] : c.files) {
      if (name.back() == '/') {
        fs::create_directories(dir / name);  // a folder where a file is expected
      } else {
        write_text(dir / name, text);
      }
    }
    const auto r = run_tool(
        kTool + " --case " + (dir / "case.json").string() + " --out " + (dir / "out").string(),
        dir);
    EXPECT_EQ(r.exit_status, 2) << r.err;
    EXPECT_NE(r.err.find(c.expected), std::string::npos) << "expected: " << c.expected << "\n"
                                                         << r.err;
    EXPECT_NE(r.err.find(c.names_file), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(fs::exists(dir / "out")) << "nothing written on input errors";
  }
}

// A tet-mesh template whose tets are ALL negatively oriented is a file convention: the tool
// reorients every tet, says so, and registers (the mixed case is an error, above).
TEST(SinewRegister, AllNegativeTetMeshTemplateIsReoriented) {
  const auto dir = scratch_dir("sinew_register_negative_tets");
  sinew::testing::TetMesh mesh = sinew::testing::make_box_mesh(8, 2, 2, 5.0);  // 40 x 10 x 10 mm
  for (Eigen::Index t = 0; t < mesh.tets.rows(); ++t) std::swap(mesh.tets(t, 2), mesh.tets(t, 3));
  write_text(dir / "box.mesh", medit_text(mesh.rest_positions, mesh.tets));
  StretchCase c = stretch_case(10.0, "mm");
  c.json["template"] = "box.mesh";
  c.json.erase("mesh");
  write_text(dir / "case.json", c.json.dump(1));
  const RunOutcome o = run_case(dir, " --max-iterations 3");
  ASSERT_EQ(o.result.exit_status, 0) << o.result.err << o.result.out;
  EXPECT_NE(o.result.out.find("template: tet mesh, 81 vertices, 192 tets (192 tets reoriented)"),
            std::string::npos)
      << o.result.out;
  EXPECT_EQ(o.report["inputs"]["tets"].get<int>(), 192);
  EXPECT_TRUE(fs::exists(dir / "out" / "result.vtu"));
  EXPECT_LT(o.report["final"]["marker_error_max"].get<double>(),
            o.report["iterations"][0]["marker_error_max"].get<double>());
}

// --- --batch: a manifest of cases, one output folder each, one case per Slurm array task.

struct BatchFixture {
  fs::path dir;       // the manifest's folder
  fs::path manifest;  // dir / "batch.json"
};

// Three cases in cases/{mm,bad,m}/ (the middle one has an unknown key), outputs in results/,
// all paths relative to the manifest.
BatchFixture batch_fixture(const std::string& name) {
  BatchFixture f;
  f.dir = scratch_dir(name);
  for (const auto& [unit, units] :
       std::vector<std::pair<double, std::string>>{{10.0, "mm"}, {0.01, "m"}}) {
    const fs::path folder = f.dir / "cases" / units;
    fs::create_directories(folder);
    const StretchCase c = stretch_case(unit, units);
    sinew::offline::io::write_obj((folder / "box.obj").string(), c.surface);
    write_text(folder / "case.json", c.json.dump(1));
  }
  fs::create_directories(f.dir / "cases" / "bad");
  fs::copy_file(f.dir / "cases" / "mm" / "box.obj", f.dir / "cases" / "bad" / "box.obj");
  nlohmann::json bad = nlohmann::json::parse(read_text(f.dir / "cases" / "mm" / "case.json"));
  bad["icp_marker"] = bad["icp_markers"];
  write_text(f.dir / "cases" / "bad" / "case.json", bad.dump(1));
  const nlohmann::json manifest = {{"cases",
                                    {{{"case", "cases/mm/case.json"}, {"out", "results/mm"}},
                                     {{"case", "cases/bad/case.json"}, {"out", "results/bad"}},
                                     {{"case", "cases/m/case.json"}, {"out", "results/m"}}}}};
  f.manifest = f.dir / "batch.json";
  write_text(f.manifest, manifest.dump(1));
  return f;
}

void expect_result(const fs::path& out) {
  SCOPED_TRACE(out.string());
  for (const char* name : {"result_surface.obj", "result.vtu", "report.json"})
    EXPECT_TRUE(fs::exists(out / name)) << name;
  if (!fs::exists(out / "report.json")) return;
  const auto report = nlohmann::json::parse(read_text(out / "report.json"));
  EXPECT_TRUE(report["termination"].is_string() && !report["termination"].empty()) << report;
  EXPECT_EQ(report["usable"], true) << report["termination"];
}

TEST(SinewRegister, BatchRunsEveryCaseAndContinuesPastAFailure) {
  const BatchFixture f = batch_fixture("sinew_register_batch_all");
  // From another working folder: the manifest's paths are relative to the manifest.
  const auto r = run_tool("cd / && unset SLURM_ARRAY_TASK_ID && " + kTool + " --batch " +
                              f.manifest.string() + " --max-iterations 30",
                          f.dir);
  std::cout << r.out << r.err;
  EXPECT_EQ(r.exit_status, 1) << r.err;
  expect_result(f.dir / "results" / "mm");
  expect_result(f.dir / "results" / "m");
  EXPECT_FALSE(fs::exists(f.dir / "results" / "bad")) << "nothing written for a bad case";
  EXPECT_NE(r.out.find("batch " + f.manifest.string() + ": 2 of 3 cases registered, 1 failed"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("[1] bad input (exit 2)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("[0] registered"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("[2] registered"), std::string::npos) << r.out;
  // stderr: the bad case's own one-line error, then the batch's line about it.
  EXPECT_NE(r.err.find((f.dir / "cases" / "bad" / "case.json").string() +
                       ":112:16: unknown key 'icp_marker'"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find(f.manifest.string() + ": case 1 (" +
                       (f.dir / "cases" / "bad" / "case.json").string() + "): bad input (exit 2)"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 2) << r.err;

  // Every case good: exit 0.
  nlohmann::json manifest = nlohmann::json::parse(read_text(f.manifest));
  manifest["cases"].erase(1);
  manifest["cases"][0]["out"] = "results2/mm";
  manifest["cases"][1]["out"] = "results2/m";
  write_text(f.dir / "good.json", manifest.dump(1));
  const auto good = run_tool("unset SLURM_ARRAY_TASK_ID && " + kTool + " --batch " +
                                 (f.dir / "good.json").string() + " --quiet",
                             f.dir);
  EXPECT_EQ(good.exit_status, 0) << good.err;
  EXPECT_EQ(good.out, "") << "--quiet";
  expect_result(f.dir / "results2" / "mm");
  expect_result(f.dir / "results2" / "m");
}

TEST(SinewRegister, BatchTaskRunsOneCase) {
  const BatchFixture f = batch_fixture("sinew_register_batch_task");
  const std::string batch = kTool + " --batch " + f.manifest.string();
  // --task 2: the third case alone, with its own exit status.
  auto r = run_tool("unset SLURM_ARRAY_TASK_ID && " + batch + " --task 2", f.dir);
  EXPECT_EQ(r.exit_status, 0) << r.err;
  expect_result(f.dir / "results" / "m");
  EXPECT_FALSE(fs::exists(f.dir / "results" / "mm"));
  EXPECT_NE(r.out.find("1 of 1 case registered, 0 failed"), std::string::npos) << r.out;
  // SLURM_ARRAY_TASK_ID picks the task when --task is absent: the bad case's status is 2.
  r = run_tool("SLURM_ARRAY_TASK_ID=1 " + batch, f.dir);
  EXPECT_EQ(r.exit_status, 2) << r.err;
  EXPECT_NE(r.err.find("unknown key 'icp_marker'"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(f.dir / "results" / "mm"));
  EXPECT_FALSE(fs::exists(f.dir / "results" / "bad"));
  // --task wins over SLURM_ARRAY_TASK_ID.
  r = run_tool("SLURM_ARRAY_TASK_ID=1 " + batch + " --task 0", f.dir);
  EXPECT_EQ(r.exit_status, 0) << r.err;
  expect_result(f.dir / "results" / "mm");
  // Out of range and malformed task indices are usage errors naming the manifest or variable.
  r = run_tool("SLURM_ARRAY_TASK_ID=3 " + batch, f.dir);
  EXPECT_EQ(r.exit_status, 2) << r.err;
  EXPECT_EQ(r.err, "sinew-register: " + f.manifest.string() +
                       ": SLURM_ARRAY_TASK_ID = 3 is not a case: the manifest has 3 cases (tasks "
                       "0-2)\n");
  r = run_tool("unset SLURM_ARRAY_TASK_ID && " + batch + " --task 7", f.dir);
  EXPECT_EQ(r.exit_status, 2) << r.err;
  EXPECT_NE(r.err.find("--task 7 is not a case: the manifest has 3 cases"), std::string::npos)
      << r.err;
  r = run_tool("SLURM_ARRAY_TASK_ID=x1 " + batch, f.dir);
  EXPECT_EQ(r.exit_status, 2) << r.err;
  EXPECT_EQ(r.err,
            "sinew-register: SLURM_ARRAY_TASK_ID = 'x1' is not a task index (a non-negative "
            "integer)\n");
}

TEST(SinewRegister, BadBatchManifestIsAnInputError) {
  const auto dir = scratch_dir("sinew_register_batch_bad");
  const nlohmann::json one = {{"case", "a/case.json"}, {"out", "out/a"}};
  struct Bad {
    std::string name, text, expected;
  };
  const std::vector<Bad> cases = {
      {"unknown_key", nlohmann::json{{"cases", {one}}, {"jobs", 2}}.dump(),
       "batch.json:1:56: unknown key 'jobs' (expected one of: cases)"},
      {"unknown_case_key",
       nlohmann::json{{"cases", {{{"case", "a.json"}, {"out", "o"}, {"outt", "p"}}}}}.dump(),
       "batch.json:1:45: unknown key 'outt' in cases[0] (expected one of: case, out, truth)"},
      {"missing_out", nlohmann::json{{"cases", {{{"case", "a.json"}}}}}.dump(),
       "batch.json:1:11: missing required field 'cases[0].out'"},
      {"empty", nlohmann::json{{"cases", nlohmann::json::array()}}.dump(),
       "batch.json:1:10: cases is empty"},
      {"same_output",
       nlohmann::json{{"cases", {one, {{"case", "b/case.json"}, {"out", "out/./a"}}}}}.dump(),
       "batch.json:1:76: cases[1].out = \"out/./a\" is also the output folder of cases[0]"},
      {"malformed", "{\"cases\": [\n", "batch.json:2:1: invalid JSON"},
      {"missing", "", "batch.json: cannot open file for reading"},
  };
  for (const Bad& c : cases) {
    SCOPED_TRACE(c.name);
    const fs::path manifest = dir / c.name / "batch.json";
    fs::create_directories(manifest.parent_path());
    if (!c.text.empty()) write_text(manifest, c.text);
    const auto r = run_tool(kTool + " --batch " + manifest.string(), dir);
    EXPECT_EQ(r.exit_status, 2) << r.err;
    EXPECT_NE(r.err.find(c.expected), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(fs::exists(dir / c.name / "out"));
  }
  // --batch with --case, and --task without --batch, are usage errors.
  auto r = run_tool(kTool + " --batch b.json --case c.json", dir);
  EXPECT_EQ(r.exit_status, 2);
  EXPECT_NE(r.err.find("--batch takes no --case"), std::string::npos) << r.err;
  r = run_tool(kTool + " --case c.json --out o --task 1", dir);
  EXPECT_EQ(r.exit_status, 2);
  EXPECT_NE(r.err.find("--task applies to --batch only"), std::string::npos) << r.err;
}

// --- Botsch & Sorkine 2008 bar: fixed and handle regions as attachments under bar.def.

// Closes each hole of a surface with a fan around the hole's centroid (the bar has one).
void cap_holes(SurfaceMesh& mesh) {
  std::map<std::pair<int, int>, int> directed;
  for (Eigen::Index f = 0; f < mesh.triangles.rows(); ++f)
    for (int k = 0; k < 3; ++k) directed[{mesh.triangles(f, k), mesh.triangles(f, (k + 1) % 3)}]++;
  // Boundary edge a→b (no b→a): the cap triangle runs b→a.
  std::map<int, int> next;  // along the reversed boundary
  for (const auto& [edge, count] : directed)
    if (!directed.count({edge.second, edge.first})) next[edge.second] = edge.first;
  std::vector<Eigen::Vector3i> caps;
  std::vector<Eigen::Vector3d> centres;
  while (!next.empty()) {
    std::vector<int> loop{next.begin()->first};
    while (true) {
      const auto it = next.find(loop.back());
      if (it == next.end()) break;
      const int to = it->second;
      next.erase(it);
      if (to == loop.front()) break;
      loop.push_back(to);
    }
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (int v : loop)
      centre += mesh.vertices.row(v).transpose() / static_cast<double>(loop.size());
    const int c =
        static_cast<int>(mesh.vertices.rows() + static_cast<Eigen::Index>(centres.size()));
    centres.push_back(centre);
    for (std::size_t i = 0; i < loop.size(); ++i)
      caps.emplace_back(loop[i], loop[(i + 1) % loop.size()], c);
  }
  const Eigen::Index nv = mesh.vertices.rows(), nf = mesh.triangles.rows();
  mesh.vertices.conservativeResize(nv + static_cast<Eigen::Index>(centres.size()), 3);
  for (std::size_t i = 0; i < centres.size(); ++i)
    mesh.vertices.row(nv + static_cast<Eigen::Index>(i)) = centres[i].transpose();
  mesh.triangles.conservativeResize(nf + static_cast<Eigen::Index>(caps.size()), 3);
  for (std::size_t i = 0; i < caps.size(); ++i)
    mesh.triangles.row(nf + static_cast<Eigen::Index>(i)) = caps[i].transpose();
}

TEST(SinewRegister, BotschBarTwistFromFixedAndHandleRegions) {
  const fs::path data = fs::path(SINEW_SHARED_DIR) / "data" / "botsch_benchmark";
  if (!fs::exists(data / "bar.off")) GTEST_SKIP() << data << " not found";
  const auto read = sinew::offline::io::read_surface_mesh((data / "bar.off").string());
  ASSERT_TRUE(read.ok()) << read.error;
  SurfaceMesh bar = *read.mesh;
  const Eigen::Index original_vertices = bar.vertices.rows();
  cap_holes(bar);
  ASSERT_TRUE(sinew::offline::io::check_surface(bar).closed_manifold())
      << sinew::offline::io::check_surface(bar).report();

  // .sel: one status per vertex after two comment lines (0 fixed, 1 free, 2 handle).
  std::vector<int> status;
  {
    std::istringstream in(read_text(data / "bar.sel"));
    for (std::string line; std::getline(in, line);)
      if (!line.empty() && line[0] != '#') status.push_back(std::stoi(line));
  }
  ASSERT_EQ(static_cast<Eigen::Index>(status.size()), original_vertices);
  Eigen::Matrix4d transform;
  {
    std::istringstream in(read_text(data / "bar.def"));
    std::string comment;
    std::getline(in, comment);
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) in >> transform(i, j);
  }
  // The full .def rotation (135° about z). The template's first equilibrium under the springs
  // only converges when tets may invert on the way (register_attached's fallback): with inversions
  // rejected the Newton line search stalls.
  // Every 8th fixed and handle vertex: enough to hold both ends.
  nlohmann::json attachments = nlohmann::json::array();
  int fixed = 0, handle = 0;
  for (Eigen::Index v = 0; v < original_vertices; ++v) {
    const int s = status[static_cast<std::size_t>(v)];
    if (s == 1) continue;
    const int count = s == 0 ? fixed++ : handle++;
    if (count % 8 != 0) continue;
    const Eigen::Vector3d p = bar.vertices.row(v).transpose();
    const Eigen::Vector3d y = s == 0 ? p : Eigen::Vector3d((transform * p.homogeneous()).head<3>());
    attachments.push_back({{"template", xyz(p)}, {"target", xyz(y)}});
  }
  const auto dir = scratch_dir("sinew_register_botsch_bar");
  ASSERT_TRUE(sinew::offline::io::write_off((dir / "bar_capped.off").string(), bar));
  const nlohmann::json c = {{"template", "bar_capped.off"},
                            {"units", "mm"},
                            {"mesh", {{"cell_size_fraction", 0.1}}},
                            {"attachments", attachments},
                            {"stop", {{"max_iterations", 2}}}};
  write_text(dir / "case.json", c.dump(1));
  const RunOutcome o = run_case(dir);
  std::cout << o.result.out;
  ASSERT_EQ(o.result.exit_status, 0) << o.result.err;
  ASSERT_TRUE(o.report.is_object());
  EXPECT_EQ(o.surface.vertices.size(), static_cast<std::size_t>(bar.vertices.rows()));
  EXPECT_EQ(o.surface.faces, bar.triangles.rows());
  EXPECT_TRUE(fs::exists(dir / "out" / "result.vtu"));
  // The handle turned: the attachment misfit ends well below the handle's displacement.
  double handle_move = 0.0;
  for (const auto& a : attachments) {
    const Eigen::Vector3d p(a["template"][0], a["template"][1], a["template"][2]);
    const Eigen::Vector3d y(a["target"][0], a["target"][1], a["target"][2]);
    handle_move = std::max(handle_move, (y - p).norm());
  }
  const double first = o.report["iterations"][0]["marker_error_max"].get<double>();
  const double last = o.report["final"]["marker_error_max"].get<double>();
  std::cout << "bar: " << attachments.size() << " attachments, handle moves up to " << handle_move
            << " mm; attachment error max " << first << " -> " << last << " mm; "
            << o.report["inputs"]["tets"] << " tets; " << o.seconds << " s; termination "
            << o.report["termination"] << "\n";
  EXPECT_LT(last, 0.01 * handle_move);
}

// --- the demo case of scripts/demo, with --truth

TEST(SinewRegister, DemoCaseMeetsItsKnownDeformation) {
  const auto dir = scratch_dir("sinew_register_demo_case");
  const auto made = run_tool(kTool + " --make-demo-case " + (dir / "case").string(), dir);
  ASSERT_EQ(made.exit_status, 0) << made.err;
  std::cout << made.out;
  for (const char* name :
       {"case.json", "template.obj", "truth_surface.obj", "markers.csv", "attachments.json"})
    EXPECT_TRUE(fs::exists(dir / "case" / name)) << name;

  // The generator is deterministic and the files are what make_demo_case builds.
  const sinew::tools::DemoCase demo = sinew::tools::make_demo_case();
  const auto truth =
      sinew::offline::io::read_surface_mesh((dir / "case/truth_surface.obj").string());
  ASSERT_TRUE(truth.ok()) << truth.error;
  EXPECT_TRUE(truth.mesh->vertices.isApprox(demo.truth_surface.vertices, 1e-14));
  EXPECT_TRUE(sinew::offline::io::check_surface(demo.template_surface).closed_manifold());
  EXPECT_GT(sinew::offline::io::check_surface(demo.template_surface).signed_volume, 0.0);
  EXPECT_TRUE(sinew::offline::io::check_surface(demo.truth_surface).closed_manifold());
  // Not a trivial case: the template is far from the truth.
  const auto before =
      sinew::offline::vertex_to_surface_distances(demo.template_surface, *truth.mesh);
  EXPECT_GT(before.max, 10.0);

  const auto start = std::chrono::steady_clock::now();
  const auto r =
      run_tool(kTool + " --case " + (dir / "case/case.json").string() + " --out " +
                   (dir / "out").string() + " --truth " + (dir / "case/truth_surface.obj").string(),
               dir);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::cout << r.out;
  ASSERT_EQ(r.exit_status, 0) << r.err;
  const auto report = nlohmann::json::parse(read_text(dir / "out" / "report.json"));
  const double diagonal = report["inputs"]["bounding_box_diagonal"].get<double>();
  ASSERT_TRUE(report.contains("truth")) << report.dump(1);
  const nlohmann::json& t = report["truth"];
  for (const char* key : {"result_to_truth_mean", "result_to_truth_max", "truth_to_result_mean",
                          "truth_to_result_max", "max_fraction_of_diagonal"})
    ASSERT_TRUE(t.contains(key)) << key;
  const double worst =
      std::max(t["result_to_truth_max"].get<double>(), t["truth_to_result_max"].get<double>());
  std::cout << "demo case: template to truth max " << before.max << " mm; result to truth mean "
            << t["result_to_truth_mean"] << " max " << t["result_to_truth_max"]
            << " mm; truth to result max " << t["truth_to_result_max"] << " mm (diagonal "
            << diagonal << " mm); " << seconds << " s\n";
  EXPECT_NEAR(t["max_fraction_of_diagonal"].get<double>(), worst / diagonal, 1e-12);
  EXPECT_LT(report["final"]["marker_error_max"].get<double>(), 0.005 * diagonal);
  EXPECT_LT(t["result_to_truth_mean"].get<double>(), 0.005 * diagonal);
  EXPECT_LT(t["truth_to_result_mean"].get<double>(), 0.005 * diagonal);
  EXPECT_LT(worst, 0.03 * diagonal);
  EXPECT_LT(worst, 0.25 * before.max);
  EXPECT_NE(r.out.find("truth: result vertices to"), std::string::npos) << r.out;
  EXPECT_LT(seconds, 120.0);

  // Outputs to look at: the histogram and convergence PNGs (PNG signature, not empty), the tets'
  // quality before and after (Fig. 17), the stretch ratio in result.vtu.
  for (const char* name : {"marker_errors.png", "convergence.png"}) {
    const std::string png = read_text(dir / "out" / name);
    ASSERT_GT(png.size(), 2000u) << name;
    EXPECT_EQ(png.substr(1, 3), "PNG") << name;
  }
  const nlohmann::json& quality = report.at("mesh_quality");
  EXPECT_EQ(quality.at("result").at("inverted_tets").get<int>(), 0);
  EXPECT_GT(quality.at("template").at("min_dihedral_degrees").get<double>(), 5.0);
  EXPECT_GT(quality.at("result").at("min_dihedral_degrees").get<double>(), 5.0);
  EXPECT_NE(quality.at("result").at("min_dihedral_degrees"),
            quality.at("template").at("min_dihedral_degrees"));  // the deformed tets, not a copy
  EXPECT_NE(read_text(dir / "out" / "result.vtu").find("Name=\"stretch_ratio\""),
            std::string::npos);

  // A --truth file that cannot be read is an input error: one line, exit 2, nothing written.
  const auto bad =
      run_tool(kTool + " --case " + (dir / "case/case.json").string() + " --out " +
                   (dir / "out_bad").string() + " --truth " + (dir / "nope.obj").string(),
               dir);
  EXPECT_EQ(bad.exit_status, 2) << bad.err;
  EXPECT_NE(bad.err.find("nope.obj"), std::string::npos) << bad.err;
  EXPECT_EQ(std::count(bad.err.begin(), bad.err.end(), '\n'), 1) << bad.err;
  EXPECT_FALSE(fs::exists(dir / "out_bad"));
  // --make-demo-case with --case is a usage error.
  const auto usage = run_tool(kTool + " --make-demo-case " + (dir / "x").string() + " --case " +
                                  (dir / "case/case.json").string(),
                              dir);
  EXPECT_EQ(usage.exit_status, 2) << usage.err;
  EXPECT_FALSE(fs::exists(dir / "x"));
}

}  // namespace

// §4.3: a surface embedded in the template is carried along. The demo's own template surface with
// texture coordinates and normals added comes out with exactly the result surface's vertices, its
// vt lines and faces kept and its (stale) normals dropped; a surface vertex far outside the
// template is an input error before any work.
TEST(SinewRegister, TransferredSurfaceKeepsItsTextureAndFollowsTheResult) {
  const auto dir = scratch_dir("sinew_register_transfer");
  ASSERT_EQ(run_tool(kTool + " --make-demo-case " + (dir / "case").string(), dir).exit_status, 0);
  std::string hires = read_text(dir / "case" / "template.obj");
  hires = "mtllib liver.mtl\nvt 0.25 0.75\nvn 0 0 1\n" + hires;
  write_text(dir / "case" / "hires.obj", hires);
  auto c = nlohmann::json::parse(read_text(dir / "case" / "case.json"));
  c["transfer"] = {"hires.obj"};
  write_text(dir / "case" / "case.json", c.dump(1));
  const auto r = run_tool(kTool + " --quiet --case " + (dir / "case/case.json").string() +
                              " --out " + (dir / "out").string(),
                          dir);
  ASSERT_EQ(r.exit_status, 0) << r.err;
  const std::string moved = read_text(dir / "out" / "transfer_hires.obj");
  EXPECT_NE(moved.find("mtllib liver.mtl\nvt 0.25 0.75\n"), std::string::npos);
  EXPECT_EQ(moved.find("\nvn "), std::string::npos);
  const auto transferred =
      sinew::offline::io::read_surface_mesh((dir / "out" / "transfer_hires.obj").string());
  const auto result =
      sinew::offline::io::read_surface_mesh((dir / "out" / "result_surface.obj").string());
  ASSERT_TRUE(transferred.mesh && result.mesh) << transferred.error << result.error;
  ASSERT_EQ(transferred.mesh->vertices.rows(), result.mesh->vertices.rows());
  EXPECT_EQ(transferred.mesh->triangles, result.mesh->triangles);
  const double moved_by = (result.mesh->vertices - sinew::offline::io::read_surface_mesh(
                                                       (dir / "case" / "template.obj").string())
                                                       .mesh->vertices)
                              .cwiseAbs()
                              .maxCoeff();
  EXPECT_GT(moved_by, 1.0);  // the demo deforms by millimetres: the transfer is not a copy
  EXPECT_LT((transferred.mesh->vertices - result.mesh->vertices).cwiseAbs().maxCoeff(), 1e-9);

  // A vertex 1 m away: one line naming the file and the vertex, exit 2, no OUTDIR.
  std::string far = read_text(dir / "case" / "hires.obj");
  const auto first_v = far.find("\nv ") + 1;
  far.replace(first_v, far.find('\n', first_v) - first_v, "v 1000 0 0");
  write_text(dir / "case" / "hires.obj", far);
  const auto bad = run_tool(kTool + " --case " + (dir / "case/case.json").string() + " --out " +
                                (dir / "out_far").string(),
                            dir);
  EXPECT_EQ(bad.exit_status, 2);
  EXPECT_NE(bad.err.find("hires.obj: vertex 0 is"), std::string::npos) << bad.err;
  EXPECT_FALSE(fs::exists(dir / "out_far"));
}
