// offline/registration/transfer: a surface in the template's frame carried by the deformation.
#include "offline/registration/transfer.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>

#include "offline/io/surface_mesh_io.hpp"
#include "offline/registration/registration_case.hpp"
#include "tests/support/run_tool.hpp"

namespace {

using sinew::offline::RegistrationInputError;
using sinew::offline::transfer_surface;

std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

const Eigen::Vector3d kShift(10.0, -2.0, 0.5);

Eigen::Vector3d shifted(const Eigen::Vector3d& p, long) {
  return p + kShift;
}

TEST(Transfer, ObjKeepsTexturesAndMaterialsMovesVerticesDropsNormals) {
  const auto dir = sinew::testing::scratch_dir("test_transfer_obj");
  const auto in = dir / "textured.obj", out = dir / "moved.obj";
  {
    std::ofstream f(in);
    f << "# a textured quad\nmtllib skin.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
         "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nusemtl skin\ng quad\n"
         "f 1/1/1 2/2/1 3/3/1\nf 1//1 3//1 4//1\n";
  }
  EXPECT_EQ(transfer_surface(in.string(), out.string(), shifted), 4);
  const std::string text = read_text(out);
  EXPECT_NE(text.find("mtllib skin.mtl\n"), std::string::npos);
  EXPECT_NE(text.find("vt 1 1\n"), std::string::npos);
  EXPECT_NE(text.find("usemtl skin\ng quad\n"), std::string::npos);
  EXPECT_EQ(text.find("vn "), std::string::npos) << text;
  // The faces keep their vertex and texture indices, without the dropped normals'.
  EXPECT_NE(text.find("f 1/1 2/2 3/3\n"), std::string::npos) << text;
  EXPECT_NE(text.find("f 1 3 4\n"), std::string::npos) << text;
  const auto read = sinew::offline::io::read_surface_mesh(out.string());
  ASSERT_TRUE(read.mesh) << read.error;
  ASSERT_EQ(read.mesh->vertices.rows(), 4);
  EXPECT_LT((read.mesh->vertices.row(2).transpose() - (Eigen::Vector3d(1, 1, 0) + kShift)).norm(),
            1e-15);
}

TEST(Transfer, OtherFormatsAreReadAndWrittenBackMoved) {
  const auto dir = sinew::testing::scratch_dir("test_transfer_off");
  const auto in = dir / "tet.off", out = dir / "moved.off";
  {
    std::ofstream f(in);
    f << "OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
  }
  EXPECT_EQ(transfer_surface(in.string(), out.string(), shifted), 4);
  const auto read = sinew::offline::io::read_surface_mesh(out.string());
  ASSERT_TRUE(read.mesh) << read.error;
  EXPECT_LT((read.mesh->vertices.row(3).transpose() - (Eigen::Vector3d(0, 0, 1) + kShift)).norm(),
            1e-12);
  EXPECT_EQ(read.mesh->triangles.rows(), 4);
}

TEST(Transfer, BadLinesAndPointsOffTheTemplateAreOneLineErrors) {
  const auto dir = sinew::testing::scratch_dir("test_transfer_errors");
  const auto bad = dir / "bad.obj";
  {
    std::ofstream f(bad);
    f << "v 0 0 0\nv 1 zero 0\nf 1 2 1\n";
  }
  try {
    transfer_surface(bad.string(), (dir / "out.obj").string(), shifted);
    FAIL() << "no error";
  } catch (const RegistrationInputError& e) {
    EXPECT_EQ(std::string(e.what()), bad.string() + ":2: expected 'v x y z' with finite numbers");
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "out.obj"));
  // The transfer's own error (a vertex off the template) reaches the caller; nothing is written.
  const auto good = dir / "good.obj";
  {
    std::ofstream f(good);
    f << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  }
  const auto refuse = [](const Eigen::Vector3d& p, long index) -> Eigen::Vector3d {
    if (index == 1) throw RegistrationInputError("vertex 1 is off the template");
    return p;
  };
  EXPECT_THROW(transfer_surface(good.string(), (dir / "out.obj").string(), refuse),
               RegistrationInputError);
  EXPECT_FALSE(std::filesystem::exists(dir / "out.obj"));
  // Without an output path the vertices are only checked.
  EXPECT_EQ(transfer_surface(good.string(), "", shifted), 3);
}

}  // namespace
