// End-to-end tests of sinew-separate: two overlapping boxes written as files, separated by the real
// binary; outputs, report numbers, and the one-line errors of bad input.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "offline/constraints/constraints.hpp"
#include "offline/io/surface_mesh_io.hpp"
#include "offline/io/tet_mesh_io.hpp"
#include "tests/support/offline_fixtures.hpp"
#include "tests/support/run_tool.hpp"

namespace {

namespace fs = std::filesystem;
using sinew::offline::TetMesh;
using sinew::testing::offline_box_mesh;
using sinew::testing::read_text;
using sinew::testing::run_tool;
using sinew::testing::scratch_dir;

const std::string kTool = std::string(SINEW_BINARY_DIR) + "/tools/sinew-separate";

/// Vertices of `mesh` strictly inside `other` (point-in-tet on other's tets; any vertex, so it
/// needs no boundary extraction; an inner vertex of one box cannot be inside the other without a
/// boundary vertex being inside too here).
int vertices_inside(const TetMesh& mesh, const TetMesh& other) {
  const Eigen::MatrixXd positions = other.vertices;
  const auto locator = sinew::offline::TetPointLocator::create(positions, other.tets);
  EXPECT_TRUE(locator.has_value());
  int inside = 0;
  for (Eigen::Index v = 0; v < mesh.vertices.rows(); ++v) {
    if (locator->locate(mesh.vertices.row(v).transpose()).status ==
        sinew::offline::EmbeddingStatus::kInside)
      ++inside;
  }
  return inside;
}

// Millimetre-sized boxes: A 12 x 5 x 5 mm, B's end overlapping A's by 0.45 mm, B's section larger
// and half a cell off A's grid (its face vertices inside A are 0.5 mm from A's sides, farther than
// the overlap, so the way out is along x).
TEST(SinewSeparate, OverlappingBoxesAreSeparated) {
  const auto dir = scratch_dir("sinew_separate_boxes");
  const TetMesh a = offline_box_mesh(12, 5, 5, 1.0, {0.0, 0.0, 0.0});
  const TetMesh b = offline_box_mesh(8, 7, 7, 1.0, {12.0 - 0.45, -1.5, -1.5});
  ASSERT_GT(vertices_inside(a, b), 0);
  ASSERT_TRUE(sinew::offline::write_vtu((dir / "a.vtu").string(), a));
  ASSERT_TRUE(sinew::offline::write_medit_mesh((dir / "b.mesh").string(), b));

  const auto out = dir / "out";
  const auto r = run_tool(kTool + " " + (dir / "a.vtu").string() + " " + (dir / "b.mesh").string() +
                              " --out " + out.string(),
                          dir);
  ASSERT_EQ(r.exit_status, 0) << r.out << r.err;
  EXPECT_TRUE(r.err.empty()) << r.err;
  EXPECT_NE(r.out.find("separated"), std::string::npos) << r.out;
  for (const char* name :
       {"a_separated.vtu", "b_separated.vtu", "a_surface.obj", "b_surface.obj", "report.json"})
    EXPECT_TRUE(fs::exists(out / name)) << name;

  const auto report = nlohmann::json::parse(read_text(out / "report.json"));
  const auto& s = report.at("summary");
  EXPECT_EQ(s.at("status"), "separated");
  EXPECT_EQ(s.at("penetrating_a_in_b_before"), 36);
  EXPECT_EQ(s.at("penetrating_b_in_a_before"), 25);
  EXPECT_EQ(s.at("penetrating_a_in_b_after"), 0);
  EXPECT_EQ(s.at("penetrating_b_in_a_after"), 0);
  EXPECT_NEAR(s.at("max_depth_before").get<double>(), 0.45, 1e-9);
  EXPECT_GT(s.at("max_displacement").get<double>(), 0.15);
  EXPECT_LT(s.at("max_displacement").get<double>(), 0.7);
  EXPECT_LT(s.at("active_tets_a").get<int>(), a.tets.rows());

  // The written meshes: same topology, separated, the far end of A untouched.
  const auto ra = sinew::offline::read_tet_mesh((out / "a_separated.vtu").string());
  const auto rb = sinew::offline::read_tet_mesh((out / "b_separated.vtu").string());
  ASSERT_TRUE(ra.ok()) << ra.error;
  ASSERT_TRUE(rb.ok()) << rb.error;
  EXPECT_EQ(ra.mesh->tets, a.tets);
  EXPECT_EQ(rb.mesh->tets, b.tets);
  EXPECT_EQ(vertices_inside(*ra.mesh, *rb.mesh), 0);
  EXPECT_EQ(vertices_inside(*rb.mesh, *ra.mesh), 0);
  for (Eigen::Index v = 0; v < a.vertices.rows(); ++v)
    if (a.vertices(v, 0) < 4.0) {
      EXPECT_EQ(ra.mesh->vertices.row(v), a.vertices.row(v));
    }
  const auto surface = sinew::offline::io::read_surface_mesh((out / "a_surface.obj").string());
  ASSERT_TRUE(surface.ok()) << surface.error;
  EXPECT_EQ(surface.mesh->triangles.rows(), 2 * 2 * (12 * 5 + 12 * 5 + 5 * 5));
  EXPECT_NE(read_text(out / "a_separated.vtu").find("Name=\"displacement\""), std::string::npos);
}

TEST(SinewSeparate, DisjointMeshesAreWrittenUnchanged) {
  const auto dir = scratch_dir("sinew_separate_disjoint");
  const TetMesh a = offline_box_mesh(3, 3, 3, 1.0, {0.0, 0.0, 0.0});
  const TetMesh b = offline_box_mesh(3, 3, 3, 1.0, {3.5, 0.0, 0.0});
  ASSERT_TRUE(sinew::offline::write_medit_mesh((dir / "a.mesh").string(), a));
  ASSERT_TRUE(sinew::offline::write_medit_mesh((dir / "b.mesh").string(), b));
  const auto out = dir / "out";
  const auto r = run_tool(kTool + " " + (dir / "a.mesh").string() + " " +
                              (dir / "b.mesh").string() + " --out " + out.string() + " --quiet",
                          dir);
  ASSERT_EQ(r.exit_status, 0) << r.out << r.err;
  EXPECT_TRUE(r.out.empty()) << r.out;
  const auto report = nlohmann::json::parse(read_text(out / "report.json"));
  EXPECT_EQ(report.at("summary").at("status"), "no_contact");
  EXPECT_EQ(report.at("summary").at("penetrating_a_in_b_before"), 0);
  EXPECT_EQ(report.at("summary").at("vertices_moved"), 0);
  const auto ra = sinew::offline::read_tet_mesh((out / "a_separated.vtu").string());
  ASSERT_TRUE(ra.ok()) << ra.error;
  EXPECT_EQ(ra.mesh->vertices, a.vertices);
}

TEST(SinewSeparate, BadInputIsOneLineAndCreatesNothing) {
  const auto dir = scratch_dir("sinew_separate_bad");
  const TetMesh a = offline_box_mesh(2, 2, 2, 1.0, {0.0, 0.0, 0.0});
  ASSERT_TRUE(sinew::offline::write_medit_mesh((dir / "a.mesh").string(), a));
  const auto out = dir / "out";

  // Missing file.
  auto r = run_tool(kTool + " " + (dir / "a.mesh").string() + " " + (dir / "absent.vtu").string() +
                        " --out " + out.string(),
                    dir);
  EXPECT_EQ(r.exit_status, 2);
  EXPECT_EQ(r.err, "sinew-separate: " + (dir / "absent.vtu").string() +
                       ": cannot open file (No such file or directory)\n");
  EXPECT_FALSE(fs::exists(out));

  // Unreadable content: a .vtu with a bad coordinate, named with its line.
  sinew::testing::write_text(dir / "bad.vtu",
                             "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\">\n");
  r = run_tool(kTool + " " + (dir / "a.mesh").string() + " " + (dir / "bad.vtu").string() +
                   " --out " + out.string(),
               dir);
  EXPECT_EQ(r.exit_status, 2);
  EXPECT_EQ(r.err, "sinew-separate: " + (dir / "bad.vtu").string() +
                       ":2: VTKFile type 'PolyData', only UnstructuredGrid is read\n");
  EXPECT_FALSE(fs::exists(out));

  // Bad option value.
  r = run_tool(kTool + " " + (dir / "a.mesh").string() + " " + (dir / "a.mesh").string() +
                   " --out " + out.string() + " --margin 2",
               dir);
  EXPECT_EQ(r.exit_status, 2);
  EXPECT_EQ(r.err,
            "sinew-separate: InterpenetrationOptions::contact_margin = 2 must be in [0, 1)\n");
  EXPECT_FALSE(fs::exists(out));
}

}  // namespace
