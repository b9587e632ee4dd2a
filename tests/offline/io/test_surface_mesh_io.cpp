// Tests of offline/io/surface_mesh_io: OBJ, OFF, STL (ASCII, binary) and PLY (ascii, binary
// little/big endian) readers, the OBJ/OFF writers, the closedness check, and the one-line error
// messages for bad input.
#include "offline/io/surface_mesh_io.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <tuple>
#include <vector>

#include "tests/support/run_tool.hpp"

namespace {

namespace fs = std::filesystem;
using sinew::offline::io::check_surface;
using sinew::offline::io::read_surface_mesh;
using sinew::offline::io::SurfaceMesh;
using sinew::offline::io::SurfaceMeshReadOptions;
using sinew::offline::io::SurfaceMeshReadResult;
using sinew::offline::io::write_obj;
using sinew::offline::io::write_off;
using sinew::testing::write_text;

/// A fresh folder for this test (ctest runs test cases in parallel processes).
fs::path test_dir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  return sinew::testing::scratch_dir(std::string("surface_mesh_io_") + info->test_suite_name() +
                                     "_" + info->name());
}

/// The box [x0, x0 + a] x [y0, y0 + b] x [z0, z0 + c], 12 triangles counter-clockwise seen from
/// outside. Coordinates exactly representable in float when the inputs are.
SurfaceMesh box(double x0, double y0, double z0, double a, double b, double c) {
  SurfaceMesh m;
  m.vertices.resize(8, 3);
  for (int i = 0; i < 8; ++i)
    m.vertices.row(i) << x0 + ((i & 1) ? a : 0.0), y0 + ((i & 2) ? b : 0.0),
        z0 + ((i & 4) ? c : 0.0);
  m.triangles.resize(12, 3);
  m.triangles << 0, 2, 1, 1, 2, 3,  // z = z0, normal -z
      4, 5, 6, 5, 7, 6,             // z = z0 + c, normal +z
      0, 1, 4, 1, 5, 4,             // y = y0, normal -y
      2, 6, 3, 3, 6, 7,             // y = y0 + b, normal +y
      0, 4, 2, 2, 4, 6,             // x = x0, normal -x
      1, 3, 5, 3, 7, 5;             // x = x0 + a, normal +x
  return m;
}

/// A box whose coordinates need all 17 digits (round trips must be exact).
SurfaceMesh awkward_box() {
  return box(0.1, -1.0 / 3.0, 2.0 / 7.0, 1e-3 * std::acos(-1.0), 12345.678901234567, 1e-9);
}

/// The box without its top face (two triangles): open, 4 boundary edges.
SurfaceMesh open_box() {
  SurfaceMesh m = box(0, 0, 0, 1, 1, 1);
  Eigen::MatrixXi t(10, 3);
  t << m.triangles.topRows(2), m.triangles.bottomRows(8);
  m.triangles = t;
  return m;
}

void expect_same_mesh(const SurfaceMeshReadResult& r, const SurfaceMesh& expected) {
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_TRUE(r.error.empty());
  ASSERT_EQ(r.mesh->vertices.rows(), expected.vertices.rows());
  ASSERT_EQ(r.mesh->triangles.rows(), expected.triangles.rows());
  EXPECT_EQ(r.mesh->vertices, expected.vertices);  // exact
  EXPECT_EQ(r.mesh->triangles, expected.triangles);
}

/// Same triangles corner by corner (positions compared exactly), for STL where the vertex order
/// is the order of first appearance.
void expect_same_geometry(const SurfaceMeshReadResult& r, const SurfaceMesh& expected) {
  ASSERT_TRUE(r.ok()) << r.error;
  ASSERT_EQ(r.mesh->vertices.rows(), expected.vertices.rows());
  ASSERT_EQ(r.mesh->triangles.rows(), expected.triangles.rows());
  for (Eigen::Index t = 0; t < expected.triangles.rows(); ++t)
    for (int c = 0; c < 3; ++c)
      EXPECT_EQ(r.mesh->vertices.row(r.mesh->triangles(t, c)),
                expected.vertices.row(expected.triangles(t, c)))
          << "triangle " << t << " corner " << c;
}

std::string g17(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

// ---------------------------------------------------------------------------------------------
// Test-local writers for the formats the library only reads.

std::string stl_ascii(const SurfaceMesh& m, const std::string& name = "box") {
  std::string s = "solid " + name + "\n";
  for (Eigen::Index t = 0; t < m.triangles.rows(); ++t) {
    s += "  facet normal 0 0 0\n    outer loop\n";
    for (int c = 0; c < 3; ++c) {
      const auto v = m.vertices.row(m.triangles(t, c));
      s += "      vertex " + g17(v(0)) + " " + g17(v(1)) + " " + g17(v(2)) + "\n";
    }
    s += "    endloop\n  endfacet\n";
  }
  return s + "endsolid " + name + "\n";
}

void put_u32_le(std::string& s, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) s += static_cast<char>((v >> (8 * i)) & 0xff);
}
void put_f32_le(std::string& s, float f) {
  std::uint32_t bits = 0;
  std::memcpy(&bits, &f, 4);
  put_u32_le(s, bits);
}

std::string stl_binary(const SurfaceMesh& m, const std::string& header80 = "binary stl") {
  std::string s = header80;
  s.resize(80, ' ');
  put_u32_le(s, static_cast<std::uint32_t>(m.triangles.rows()));
  for (Eigen::Index t = 0; t < m.triangles.rows(); ++t) {
    for (int a = 0; a < 3; ++a) put_f32_le(s, 0.0f);  // normal
    for (int c = 0; c < 3; ++c)
      for (int a = 0; a < 3; ++a)
        put_f32_le(s, static_cast<float>(m.vertices(m.triangles(t, c), a)));
    s += std::string(2, '\0');  // attribute byte count
  }
  return s;
}

enum class PlyEncoding { ascii, little, big };

/// Appends the bytes of a scalar in the chosen byte order.
template <class T>
void put(std::string& s, T v, PlyEncoding e) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  const std::uint16_t one = 1;
  char first = 0;
  std::memcpy(&first, &one, 1);
  const bool host_little = first == 1;
  if ((e == PlyEncoding::big) == host_little) std::reverse(b, b + sizeof(T));
  s.append(b, sizeof(T));
}

/// A PLY with double (or float) x,y,z plus skipped properties (a normal, a colour), face lists
/// with uchar (or int) counts and int (or uint) indices plus a skipped face property, and an extra
/// element before and after that must be skipped. `quad` appends one quad face.
std::string ply(const SurfaceMesh& m, PlyEncoding e, bool float_xyz, bool int_counts,
                bool quad = false) {
  const Eigen::Index nf = m.triangles.rows() + (quad ? 1 : 0);
  std::string s = "ply\n";
  s += e == PlyEncoding::ascii    ? "format ascii 1.0\n"
       : e == PlyEncoding::little ? "format binary_little_endian 1.0\n"
                                  : "format binary_big_endian 1.0\n";
  s += "comment written by test_surface_mesh_io\n";
  s += "element camera 1\nproperty float view_px\nproperty list uchar int tags\n";
  s += "element vertex " + std::to_string(m.vertices.rows()) + "\n";
  s += "property float nx\n";
  const char* xyz_type = float_xyz ? "float" : "double";
  for (const char* a : {"x", "y", "z"}) s += std::string("property ") + xyz_type + " " + a + "\n";
  s += "property uchar red\n";
  s += "element face " + std::to_string(nf) + "\n";
  s += "property short flags\n";
  s +=
      std::string("property list ") + (int_counts ? "int uint" : "uchar int") + " vertex_indices\n";
  s += "property double quality\n";
  s += "element edge 1\nproperty int vertex1\nproperty int vertex2\n";
  s += "end_header\n";
  const auto face = [&](std::vector<int> corners) {
    if (e == PlyEncoding::ascii) {
      s += "7 " + std::to_string(corners.size());
      for (int c : corners) s += " " + std::to_string(c);
      s += " 0.5\n";
      return;
    }
    put<std::int16_t>(s, 7, e);
    if (int_counts)
      put<std::int32_t>(s, static_cast<std::int32_t>(corners.size()), e);
    else
      put<std::uint8_t>(s, static_cast<std::uint8_t>(corners.size()), e);
    for (int c : corners) {
      if (int_counts)
        put<std::uint32_t>(s, static_cast<std::uint32_t>(c), e);
      else
        put<std::int32_t>(s, c, e);
    }
    put<double>(s, 0.5, e);
  };
  if (e == PlyEncoding::ascii) {
    s += "1.5 3 10 20 30\n";
  } else {
    put<float>(s, 1.5f, e);
    put<std::uint8_t>(s, 3, e);
    for (int v : {10, 20, 30}) put<std::int32_t>(s, v, e);
  }
  for (Eigen::Index i = 0; i < m.vertices.rows(); ++i) {
    if (e == PlyEncoding::ascii) {
      s += "0.25";
      for (int a = 0; a < 3; ++a) s += " " + g17(m.vertices(i, a));
      s += " 200\n";
    } else {
      put<float>(s, 0.25f, e);
      for (int a = 0; a < 3; ++a) {
        if (float_xyz)
          put<float>(s, static_cast<float>(m.vertices(i, a)), e);
        else
          put<double>(s, m.vertices(i, a), e);
      }
      put<std::uint8_t>(s, 200, e);
    }
  }
  for (Eigen::Index t = 0; t < m.triangles.rows(); ++t)
    face({m.triangles(t, 0), m.triangles(t, 1), m.triangles(t, 2)});
  if (quad) face({0, 1, 3, 2});
  if (e == PlyEncoding::ascii) {
    s += "0 1\n";
  } else {
    put<std::int32_t>(s, 0, e);
    put<std::int32_t>(s, 1, e);
  }
  return s;
}

/// Reads `text` written to `name` in this test's folder; returns the result.
SurfaceMeshReadResult read_text(const std::string& name, const std::string& text,
                                const SurfaceMeshReadOptions& options = {}) {
  const fs::path path = test_dir() / name;
  write_text(path, text);
  return read_surface_mesh(path.string(), options);
}

/// Expects failure with a message starting "<file>:<line>: " (text formats) and containing `what`.
void expect_error(const SurfaceMeshReadResult& r, const std::string& file_and_position,
                  const std::string& what) {
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error.find(file_and_position), std::string::npos) << r.error;
  EXPECT_NE(r.error.find(what), std::string::npos) << r.error;
  EXPECT_EQ(r.error.find('\n'), std::string::npos) << "one line: " << r.error;
}

// ---------------------------------------------------------------------------------------------
// Round trips

TEST(SurfaceMeshIo, ObjRoundTripIsExact) {
  const fs::path path = test_dir() / "box.obj";
  const SurfaceMesh m = awkward_box();
  std::string error;
  ASSERT_TRUE(write_obj(path.string(), m, &error)) << error;
  const auto r = read_surface_mesh(path.string());
  expect_same_mesh(r, m);
  EXPECT_EQ(r.polygons_triangulated, 0);
}

TEST(SurfaceMeshIo, OffRoundTripIsExactAndExtensionIsCaseInsensitive) {
  const fs::path path = test_dir() / "BOX.OFF";
  const SurfaceMesh m = awkward_box();
  std::string error;
  ASSERT_TRUE(write_off(path.string(), m, &error)) << error;
  expect_same_mesh(read_surface_mesh(path.string()), m);
}

TEST(SurfaceMeshIo, StlAndPlyWritersRoundTrip) {
  const SurfaceMesh m = awkward_box();
  std::string error;
  // PLY (ASCII, %.17g) is exact; binary STL stores float32 and repeats vertices per facet, which
  // the reader welds back into the same indexed mesh.
  const fs::path ply = test_dir() / "box_written.ply";
  ASSERT_TRUE(write_surface_mesh(ply.string(), m, &error)) << error;
  expect_same_mesh(read_surface_mesh(ply.string()), m);
  // float32: a box of ordinary size (the awkward one's 1e-9 extent would collapse).
  const SurfaceMesh plain = box(0.1, -0.3, 0.2, 1.5, 2.5, 3.5);
  const fs::path stl = test_dir() / "box_written.STL";
  ASSERT_TRUE(write_surface_mesh(stl.string(), plain, &error)) << error;
  const auto r = read_surface_mesh(stl.string());
  ASSERT_TRUE(r.mesh.has_value()) << "error: " << r.error;
  ASSERT_EQ(r.mesh->vertices.rows(), plain.vertices.rows());
  ASSERT_EQ(r.mesh->triangles.rows(), plain.triangles.rows());
  for (Eigen::Index f = 0; f < plain.triangles.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d expected = plain.vertices.row(plain.triangles(f, k)).transpose();
      const Eigen::Vector3d got = r.mesh->vertices.row(r.mesh->triangles(f, k)).transpose();
      EXPECT_LT((got - expected).norm(), 1e-6 * (1.0 + expected.norm()));
    }
  EXPECT_FALSE(write_surface_mesh((test_dir() / "box.xyz").string(), m, &error));
  EXPECT_NE(error.find("unknown surface format '.xyz'"), std::string::npos) << error;
}

TEST(SurfaceMeshIo, WritersAreAtomicAndLeaveNoTemporaryFiles) {
  const fs::path dir = test_dir();
  const SurfaceMesh m = box(0, 0, 0, 1, 2, 3);
  write_text(dir / "out.obj", "old contents");
  ASSERT_TRUE(write_obj((dir / "out.obj").string(), m));
  ASSERT_TRUE(write_off((dir / "out.off").string(), m));
  int files = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    ++files;
    EXPECT_EQ(entry.path().string().find(".tmp"), std::string::npos) << entry.path();
  }
  EXPECT_EQ(files, 2);
  expect_same_mesh(read_surface_mesh((dir / "out.obj").string()), m);

  // An unwritable destination: an error naming the file, and nothing left behind.
  std::string error;
  EXPECT_FALSE(write_obj((dir / "missing_folder" / "x.obj").string(), m, &error));
  EXPECT_NE(error.find("missing_folder/x.obj"), std::string::npos) << error;
  // Bad indices are refused before anything is written.
  SurfaceMesh bad = m;
  bad.triangles(3, 1) = 8;
  EXPECT_FALSE(write_off((dir / "bad.off").string(), bad, &error));
  EXPECT_NE(error.find("outside 0..7"), std::string::npos) << error;
  EXPECT_FALSE(fs::exists(dir / "bad.off"));
}

TEST(SurfaceMeshIo, ObjCornerFormsNegativeIndicesAndPolygons) {
  // The box's top as a quad with v/vt/vn corners, the rest with v//vn and negative indices.
  const std::string text =
      "# box\nmtllib box.mtl\no box\n"
      "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
      "vt 0 0\nvt 1 0\nvn 0 0 1\n"
      "v 0 0 1 1.0\nv 1 0 1 0.5 0.5 0.5\nv 0 1 1\nv 1 1 1\n"
      "g top\nusemtl skin\ns 1\n"
      "f 5/1/1 6/2/1 8/1/1 7/2/1\n"
      "f -8//1 -6//1 -7//1\nf 2 3 4\n"
      "f 1/1 2/2 5/1\nf 2 6 5\nf 3 7 4\nf 4 7 8\nf 1 5 3\nf 3 5 7\nf 2 4 6\nf 4 8 6\n";
  const auto r = read_text("box.obj", text);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.polygons_triangulated, 1);
  const SurfaceMesh expected = box(0, 0, 0, 1, 1, 1);
  EXPECT_EQ(r.mesh->vertices, expected.vertices);
  ASSERT_EQ(r.mesh->triangles.rows(), 12);
  // Fan of the quad 4 5 7 6 (0-based): (4 5 7), (4 7 6).
  EXPECT_EQ(r.mesh->triangles.row(0), Eigen::RowVector3i(4, 5, 7));
  EXPECT_EQ(r.mesh->triangles.row(1), Eigen::RowVector3i(4, 7, 6));
  EXPECT_EQ(r.mesh->triangles.row(2), Eigen::RowVector3i(0, 2, 1));
  const auto check = check_surface(*r.mesh);
  EXPECT_TRUE(check.closed_manifold()) << check.report();
  EXPECT_DOUBLE_EQ(check.signed_volume, 1.0);
}

TEST(SurfaceMeshIo, OffHeaderVariantsColoursAndPolygons) {
  // Counts on the header line, comments, per-vertex and per-face colours, a quad.
  const std::string text =
      "COFF 8 7 0 # counts here\n"
      "0 0 0 255 0 0 255\n1 0 0 255 0 0 255\n0 1 0 1 1 1 1\n1 1 0 1 1 1 1\n"
      "0 0 1 1 1 1 1\n1 0 1 1 1 1 1\n0 1 1 1 1 1 1\n1 1 1 1 1 1 1\n"
      "3 0 2 1\n3 1 2 3\n4 4 5 7 6 0.5 0.5 0.5\n3 0 1 4\n3 1 5 4\n"
      "3 2 6 3 # comment\n3 3 6 7\n";
  const auto r = read_text("partial.off", text);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.polygons_triangulated, 1);
  EXPECT_EQ(r.mesh->vertices.rows(), 8);
  EXPECT_EQ(r.mesh->triangles.rows(), 8);
  EXPECT_EQ(r.mesh->triangles.row(2), Eigen::RowVector3i(4, 5, 7));
}

TEST(SurfaceMeshIo, StlAsciiAndBinaryGiveTheSameIndexedMesh) {
  const SurfaceMesh m = box(-1.5, 0.25, 100.0, 2.0, 0.125, 3.5);  // exact in float
  const auto ascii = read_text("box_ascii.stl", stl_ascii(m));
  const auto binary = read_text("box_binary.stl", stl_binary(m));
  expect_same_geometry(ascii, m);
  expect_same_geometry(binary, m);
  ASSERT_TRUE(ascii.ok() && binary.ok());
  EXPECT_EQ(ascii.mesh->vertices, binary.mesh->vertices);
  EXPECT_EQ(ascii.mesh->triangles, binary.mesh->triangles);
  EXPECT_EQ(binary.merged_stl_corners, 36 - 8);
  EXPECT_TRUE(check_surface(*binary.mesh).closed_manifold());
}

TEST(SurfaceMeshIo, StlAsciiKeepsFullDoublePrecision) {
  const SurfaceMesh m = awkward_box();
  expect_same_geometry(read_text("awkward.stl", stl_ascii(m)), m);
}

TEST(SurfaceMeshIo, BinaryStlMayStartWithSolidAndMergesSignedZeros) {
  SurfaceMesh m = box(-1, -1, -1, 1, 1, 1);  // corners with coordinate 0 written as +0
  std::string bytes = stl_binary(m, "solid but actually binary");
  const auto r = read_text("solid_binary.stl", bytes);
  expect_same_geometry(r, m);
  // Writing -0 for one corner must not create a ninth vertex.
  SurfaceMesh negative_zero = m;
  for (Eigen::Index i = 0; i < negative_zero.vertices.size(); ++i) {
    if (negative_zero.vertices(i) == 0.0) negative_zero.vertices(i) = -0.0;
  }
  SurfaceMesh mixed;
  mixed.vertices.resize(16, 3);
  mixed.vertices << m.vertices, negative_zero.vertices;
  mixed.triangles = m.triangles;
  mixed.triangles.bottomRows(6).array() += 8;  // the second half uses the -0 copies
  const auto r2 = read_text("signed_zero.stl", stl_binary(mixed));
  ASSERT_TRUE(r2.ok()) << r2.error;
  EXPECT_EQ(r2.mesh->vertices.rows(), 8);
}

class SurfaceMeshIoPly : public ::testing::TestWithParam<std::tuple<PlyEncoding, bool, bool>> {};

TEST_P(SurfaceMeshIoPly, IsExactAndSkipsOtherPropertiesAndElements) {
  const auto [encoding, float_xyz, int_counts] = GetParam();
  const SurfaceMesh m = float_xyz ? box(-1.5, 0.25, 100.0, 2.0, 0.125, 3.5) : awkward_box();
  expect_same_mesh(read_text("box.ply", ply(m, encoding, float_xyz, int_counts)), m);
  // With a quad: fan-triangulated into two more triangles.
  const auto r = read_text("quad.ply", ply(m, encoding, float_xyz, int_counts, true));
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.polygons_triangulated, 1);
  ASSERT_EQ(r.mesh->triangles.rows(), 14);
  EXPECT_EQ(r.mesh->triangles.row(12), Eigen::RowVector3i(0, 1, 3));
  EXPECT_EQ(r.mesh->triangles.row(13), Eigen::RowVector3i(0, 3, 2));
}

INSTANTIATE_TEST_SUITE_P(
    AllEncodings, SurfaceMeshIoPly,
    ::testing::Combine(::testing::Values(PlyEncoding::ascii, PlyEncoding::little, PlyEncoding::big),
                       ::testing::Bool(), ::testing::Bool()));

TEST(SurfaceMeshIo, PlyBinaryEndiannessesGiveTheSameMesh) {
  const SurfaceMesh m = awkward_box();
  const auto little = read_text("little.ply", ply(m, PlyEncoding::little, false, false));
  const auto big = read_text("big.ply", ply(m, PlyEncoding::big, false, true));
  const auto ascii = read_text("ascii.ply", ply(m, PlyEncoding::ascii, false, false));
  ASSERT_TRUE(little.ok() && big.ok() && ascii.ok()) << little.error << big.error << ascii.error;
  EXPECT_EQ(little.mesh->vertices, big.mesh->vertices);
  EXPECT_EQ(little.mesh->vertices, ascii.mesh->vertices);
  EXPECT_EQ(little.mesh->triangles, big.mesh->triangles);
}

// ---------------------------------------------------------------------------------------------
// Bad input: one line naming the file and the line (or byte offset)

TEST(SurfaceMeshIo, ObjErrorsNameFileAndLine) {
  const std::string v = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  expect_error(read_text("a.obj", v + "f 1 2 4\n"),
               "a.obj:4: ", "references vertex 4, but there are 3 vertices");
  expect_error(read_text("b.obj", v + "f 1 2 -4\n"), "b.obj:4: ", "relative index -4");
  expect_error(read_text("c.obj", v + "f 1 0 2\n"), "c.obj:4: ", "vertex 0");
  expect_error(read_text("d.obj", "v 0 0 0\nv 1 nan 0\n"), "d.obj:2: ", "non-finite coordinate");
  expect_error(read_text("e.obj", "v 0 0 0\nv 1 1e999 0\n"), "e.obj:2: ", "non-finite coordinate");
  expect_error(read_text("f.obj", v + "\nf 1 2 2\n"),
               "f.obj:5: ", "is degenerate: it repeats vertex 2");
  expect_error(read_text("g.obj", v + "f 1 2\n"), "g.obj:4: ", "2 corners, at least 3 needed");
  expect_error(read_text("h.obj", "v 0 0\n"), "h.obj:1: ", "expected 3 numbers");
  expect_error(read_text("i.obj", "v 0 0 x\n"), "i.obj:1: ", "expected a number, got 'x'");
  expect_error(read_text("j.obj", v + "f 1 2 a/3\n"), "j.obj:4: ", "'a/3'");
  expect_error(read_text("k.obj", v), "k.obj: ", "empty mesh (no faces)");
  expect_error(read_text("l.obj", "# nothing\n"), "l.obj: ", "empty mesh (no vertices)");
}

TEST(SurfaceMeshIo, DegenerateFacesCanBeDropped) {
  const std::string text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 1 2\n";
  SurfaceMeshReadOptions options;
  options.drop_degenerate_faces = true;
  const auto r = read_text("drop.obj", text, options);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.dropped_faces, 1);
  EXPECT_EQ(r.mesh->triangles.rows(), 1);
}

TEST(SurfaceMeshIo, OffErrors) {
  expect_error(read_text("a.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n"),
               "a.off:4: ", "file ends before a coordinate of vertex 2 of 3 (truncated file?)");
  expect_error(read_text("b.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n"),
               "b.off:6: ", "references vertex 3, but there are 3 vertices (numbered from 0)");
  expect_error(read_text("c.off", "PLY\n"), "c.off:1: ", "expected the header 'OFF'");
  expect_error(read_text("d.off", "OFF\n3 1 0\n0 0 0\n1 inf 0\n0 1 0\n3 0 1 2\n"),
               "d.off:4: ", "non-finite");
  expect_error(read_text("e.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 2\n"),
               "e.off:7: ", "after the 1 faces declared at line 2");
  expect_error(read_text("f.off", "OFF BINARY\n"), "f.off:1: ", "binary OFF is not supported");
  expect_error(read_text("g.off", "OFF\n0 0 0\n"), "g.off: ", "empty mesh");
}

TEST(SurfaceMeshIo, StlErrors) {
  const SurfaceMesh m = box(0, 0, 0, 1, 1, 1);
  std::string truncated = stl_binary(m);
  truncated.resize(truncated.size() - 7);
  expect_error(read_text("a.stl", truncated), "a.stl: byte 80: ",
               "header says 12 facets (84 + 50*n = 684 bytes), but the file has 677 bytes "
               "(truncated file?)");
  // Truncated binary file whose header starts with "solid": still recognised as binary.
  std::string solid = stl_binary(m, "solid binary");
  solid.resize(solid.size() - 50);
  expect_error(read_text("b.stl", solid), "b.stl: byte 80: ", "truncated file?");
  std::string nan_corner = stl_binary(m);
  const float nan = std::nanf("");
  std::memcpy(&nan_corner[84 + 50 * 2 + 12 + 12 + 4], &nan, 4);  // facet 2, corner 1, y
  expect_error(read_text("c.stl", nan_corner), "c.stl: byte 208: ", "facet 2 has a non-finite");
  std::string ascii = stl_ascii(m);
  ascii = ascii.substr(0, ascii.find("endloop", 200));
  expect_error(read_text("d.stl", ascii), "d.stl:", "file ends inside the facet started at line");
  expect_error(
      read_text("e.stl", "solid x\n  facet normal 0 0 0\n    outer loop\n      vertex 0 0\n"),
      "e.stl:4: ", "vertex: expected 3 numbers, found 2");
  expect_error(read_text("f.stl", "abc"), "f.stl: ", "too short for a binary STL");
  // A facet whose two corners coincide collapses to a degenerate face.
  SurfaceMesh collapsed = m;
  collapsed.vertices.row(1) = collapsed.vertices.row(0);
  expect_error(read_text("g.stl", stl_ascii(collapsed)), "g.stl:2: ", "is degenerate");
}

TEST(SurfaceMeshIo, PlyErrors) {
  const SurfaceMesh m = box(0, 0, 0, 1, 1, 1);
  std::string unsupported = ply(m, PlyEncoding::ascii, false, false);
  unsupported.replace(unsupported.find("property float nx"), 17, "property int64 nx");
  expect_error(read_text("a.ply", unsupported),
               "a.ply:8: ", "unsupported PLY property type 'int64'");
  std::string truncated = ply(m, PlyEncoding::little, false, false);
  truncated.resize(truncated.size() - 40);
  expect_error(read_text("b.ply", truncated), "b.ply: byte ", "truncated file?");
  std::string out_of_range = ply(m, PlyEncoding::ascii, false, false);
  out_of_range.replace(out_of_range.find("7 3 1 2 3 0.5"), 13, "7 3 1 2 9 0.5");
  const auto r = read_text("c.ply", out_of_range);
  expect_error(r, "c.ply:", "references vertex 9, but there are 8 vertices");
  std::string no_face =
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty "
      "float y\nproperty float z\nend_header\n0 0 0\n";
  expect_error(read_text("d.ply", no_face), "d.ply:", "no 'element face'");
  std::string no_z =
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float "
      "y\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n0 0\n";
  expect_error(read_text("e.ply", no_z), "e.ply:3: ", "element vertex has no property 'z'");
  expect_error(read_text("f.ply", "ply\nformat ascii 1.0\n"), "f.ply:", "before 'end_header'");
}

TEST(SurfaceMeshIo, UnknownExtensionAndMissingFile) {
  const fs::path dir = test_dir();
  auto r = read_surface_mesh((dir / "mesh.vtk").string());
  expect_error(r, "mesh.vtk: ", "unknown surface-mesh extension '.vtk'");
  r = read_surface_mesh((dir / "missing.obj").string());
  expect_error(r, "missing.obj: ", "cannot open file");
}

// ---------------------------------------------------------------------------------------------
// Closedness and volume

TEST(SurfaceMeshIoCheck, ClosedBoxHasItsVolume) {
  const auto check = check_surface(box(10, 20, 30, 2, 3, 4));
  EXPECT_TRUE(check.closed());
  EXPECT_TRUE(check.closed_manifold()) << check.report();
  EXPECT_EQ(check.edges, 18);
  EXPECT_EQ(check.boundary_edges, 0);
  EXPECT_DOUBLE_EQ(check.signed_volume, 24.0);
  EXPECT_EQ(check.report().rfind("closed manifold", 0), 0u) << check.report();
}

TEST(SurfaceMeshIoCheck, OpenBoxHasFourBoundaryEdges) {
  const auto check = check_surface(open_box());
  EXPECT_FALSE(check.closed());
  EXPECT_FALSE(check.closed_manifold());
  EXPECT_EQ(check.boundary_edges, 4);
  EXPECT_EQ(check.non_manifold_edges, 0);
  EXPECT_EQ(check.unreferenced_vertices, 0);
  EXPECT_NE(check.report().find("4 boundary edges"), std::string::npos) << check.report();
}

TEST(SurfaceMeshIoCheck, InvertedAndInconsistentAndNonManifold) {
  SurfaceMesh inverted = box(0, 0, 0, 1, 1, 1);
  inverted.triangles.col(1).swap(inverted.triangles.col(2));
  const auto inv = check_surface(inverted);
  EXPECT_TRUE(inv.closed_manifold());
  EXPECT_DOUBLE_EQ(inv.signed_volume, -1.0);

  SurfaceMesh one_flipped = box(0, 0, 0, 1, 1, 1);
  std::swap(one_flipped.triangles(5, 1), one_flipped.triangles(5, 2));
  const auto flipped = check_surface(one_flipped);
  EXPECT_TRUE(flipped.closed());
  EXPECT_FALSE(flipped.closed_manifold());
  EXPECT_EQ(flipped.inconsistent_edges, 3);

  SurfaceMesh fin = box(0, 0, 0, 1, 1, 1);
  fin.vertices.conservativeResize(9, 3);
  fin.vertices.row(8) << 0.5, 0.5, 2.0;
  fin.triangles.conservativeResize(13, 3);
  fin.triangles.row(12) << 5, 6, 8;  // the top diagonal 5-6 now has three triangles
  const auto fins = check_surface(fin);
  EXPECT_EQ(fins.non_manifold_edges, 1);
  EXPECT_EQ(fins.boundary_edges, 2);
  EXPECT_FALSE(fins.closed());
}

// ---------------------------------------------------------------------------------------------
// Real files from ../shared/data (skipped when absent)

fs::path shared_data(const std::string& relative) {
  return fs::path(SINEW_SHARED_DIR) / "data" / relative;
}

TEST(SurfaceMeshIoRealData, LibpgoBunnyObj) {
  const fs::path path = shared_data("libpgo_models/bunny.obj");
  if (!fs::exists(path)) GTEST_SKIP() << path << " not found (../shared is absent)";
  const auto r = read_surface_mesh(path.string());
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.mesh->vertices.rows(), 4214);
  EXPECT_EQ(r.mesh->triangles.rows(), 8424);
  const auto check = check_surface(*r.mesh);
  EXPECT_EQ(check.unreferenced_vertices, 0) << check.report();
}

TEST(SurfaceMeshIoRealData, FemurPairBinaryStlIsClosed) {
  const fs::path path = shared_data("femur_pair/femur_reference.stl");
  if (!fs::exists(path)) GTEST_SKIP() << path << " not found (../shared is absent)";
  const auto r = read_surface_mesh(path.string());
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.mesh->vertices.rows(), 1622);
  EXPECT_EQ(r.mesh->triangles.rows(), 3240);
  const auto check = check_surface(*r.mesh);
  EXPECT_TRUE(check.closed_manifold()) << check.report();
  EXPECT_NE(check.signed_volume, 0.0);
}

TEST(SurfaceMeshIoRealData, BotschBarOffHasOneHole) {
  const fs::path path = shared_data("botsch_benchmark/bar.off");
  if (!fs::exists(path)) GTEST_SKIP() << path << " not found (../shared is absent)";
  const auto r = read_surface_mesh(path.string());
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.mesh->vertices.rows(), 6084);
  EXPECT_EQ(r.mesh->triangles.rows(), 12106);
  const auto check = check_surface(*r.mesh);
  EXPECT_EQ(check.boundary_edges, 60) << check.report();
  EXPECT_EQ(check.non_manifold_edges, 0);
  EXPECT_EQ(check.inconsistent_edges, 0);
}

}  // namespace
