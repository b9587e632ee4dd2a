// Tests of offline/io/point_list_io: marker lists from CSV, JSON, 3D Slicer .mrk.json and .fcsv,
// RAS/LPS conversion, point pairs, and the one-line error messages for bad input.
#include "offline/io/point_list_io.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "tests/support/run_tool.hpp"

namespace {

namespace fs = std::filesystem;
using sinew::offline::io::convert_coordinate_system;
using sinew::offline::io::CoordinateSystem;
using sinew::offline::io::PointList;
using sinew::offline::io::PointListReadResult;
using sinew::offline::io::PointPairsReadResult;
using sinew::offline::io::read_point_list;
using sinew::offline::io::read_point_pairs;
using sinew::testing::write_text;

/// A fresh folder for this test (ctest runs test cases in parallel processes).
fs::path test_dir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  return sinew::testing::scratch_dir(std::string("point_list_io_") + info->test_suite_name() + "_" +
                                     info->name());
}

PointListReadResult read_points(const std::string& name, const std::string& text) {
  const fs::path path = test_dir() / name;
  write_text(path, text);
  return read_point_list(path.string());
}

PointPairsReadResult read_pairs(const std::string& name, const std::string& text) {
  const fs::path path = test_dir() / name;
  write_text(path, text);
  return read_point_pairs(path.string());
}

/// Three points whose coordinates need all 17 digits.
Eigen::MatrixXd points3() {
  Eigen::MatrixXd p(3, 3);
  p << 0.1, -1.0 / 3.0, 2.0 / 7.0,       //
      -12.5, 1e-9, 123456.789012345678,  //
      3, 4, -5;
  return p;
}

std::string g17(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

std::string row(const Eigen::MatrixXd& p, Eigen::Index i, const std::string& separator) {
  return g17(p(i, 0)) + separator + g17(p(i, 1)) + separator + g17(p(i, 2));
}

std::string json_row(const Eigen::MatrixXd& p, Eigen::Index i) {
  return "[" + row(p, i, ", ") + "]";
}

/// Failure whose single-line message contains `position` (e.g. "m.csv:7: ") and `what`.
template <class Result>
void expect_error(const Result& r, const std::string& position, const std::string& what) {
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error.find(position), std::string::npos) << r.error;
  EXPECT_NE(r.error.find(what), std::string::npos) << r.error;
  EXPECT_EQ(r.error.find('\n'), std::string::npos) << "one line: " << r.error;
}

// ---------------------------------------------------------------------------------------------
// CSV

TEST(PointListIo, CsvThreeColumnsWithHeaderRoundTripsExactly) {
  const Eigen::MatrixXd p = points3();
  const std::string text = "# markers picked on the CT\nx,y,z\n" + row(p, 0, ",") + "\n" +
                           row(p, 1, " , ") + "\n\n" + row(p, 2, ",") + "\n";
  const auto r = read_points("markers.csv", text);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.list->points, p);
  EXPECT_TRUE(r.list->labels.empty());
  EXPECT_EQ(r.list->coordinate_system, CoordinateSystem::unspecified);
}

TEST(PointListIo, CsvWhitespaceSeparatedWithoutHeader) {
  const Eigen::MatrixXd p = points3();
  const std::string text = row(p, 0, " ") + "\r\n" + row(p, 1, "\t") + "\r\n" + row(p, 2, "   ");
  const auto r = read_points("markers.txt", text);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.list->points, p);
}

TEST(PointListIo, CsvLabelColumnWithQuotes) {
  const Eigen::MatrixXd p = points3();
  const std::string text = "label,x,y,z\n\"tip, left\"," + row(p, 0, ",") + "\n7," +
                           row(p, 1, ",") + "\n  \"say \"\"hi\"\"\" ," + row(p, 2, ",") + "\n";
  const auto r = read_points("labelled.CSV", text);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.list->points, p);
  EXPECT_EQ(r.list->labels, (std::vector<std::string>{"tip, left", "7", "say \"hi\""}));
}

TEST(PointListIo, CsvErrorsNameFileAndLine) {
  // The brief's example: line 7 has two numbers.
  expect_error(read_points("markers.csv", "x,y,z\n1,2,3\n# c\n4,5,6\n\n7,8,9\n10,11\n"),
               "markers.csv:7: ", "expected 3 numbers, found 2");
  EXPECT_NE(read_points("markers.csv", "x,y,z\n1,2,3\n# c\n4,5,6\n\n7,8,9\n10,11\n")
                .error.find("markers.csv:7: expected 3 numbers, found 2"),
            std::string::npos);
  expect_error(read_points("a.csv", "1,2,3\n4,nan,6\n"),
               "a.csv:2: ", "field 2 (y) is not finite: 'nan'");
  expect_error(read_points("b.csv", "1,2,3\n4,1e999,6\n"), "b.csv:2: ", "is not finite");
  expect_error(read_points("c.csv", "1,2,3\n4,five,6\n"),
               "c.csv:2: ", "field 2 (y): expected a number, got 'five'");
  expect_error(read_points("d.csv", "1,2,3\n1,,3\n"), "d.csv:2: ", "field 2 (y) is empty");
  expect_error(read_points("e.csv", "a,1,2,3\nb,1,2\n"),
               "e.csv:2: ", "expected a label and 3 numbers (like line 1), found 3 fields");
  expect_error(read_points("f.csv", "1,2,3,4,5\n"),
               "f.csv:1: ", "expected 3 numbers or a label and 3 numbers, found 5 fields");
  expect_error(read_points("g.csv", "x,y,z\n"), "g.csv: ", "no points");
  expect_error(read_points("h.csv", "\"open,1,2,3\n"), "h.csv:1: ", "unterminated double quote");
  expect_error(read_points("i.xyz", "1 2 3\n"), "i.xyz: ", "unknown point-list extension '.xyz'");
  const auto missing = read_point_list((test_dir() / "missing.csv").string());
  expect_error(missing, "missing.csv: ", "cannot open file");
}

// ---------------------------------------------------------------------------------------------
// JSON

TEST(PointListIo, JsonArrayOfPoints) {
  const Eigen::MatrixXd p = points3();
  const auto r = read_points(
      "m.json", "[" + json_row(p, 0) + ",\n " + json_row(p, 1) + ", " + json_row(p, 2) + "]");
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.list->points, p);
  EXPECT_TRUE(r.list->labels.empty());
}

TEST(PointListIo, JsonObjectWithPointsAndCoordinateSystem) {
  const Eigen::MatrixXd p = points3();
  const auto r =
      read_points("m.json", "{\"coordinateSystem\": \"RAS\", \"points\": [" + json_row(p, 0) +
                                ", {\"label\": \"b\", \"position\": " + json_row(p, 1) + "}, " +
                                json_row(p, 2) + "]}");
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.list->points, p);
  EXPECT_EQ(r.list->coordinate_system, CoordinateSystem::ras);
  EXPECT_EQ(r.list->labels, (std::vector<std::string>{"", "b", ""}));
}

TEST(PointListIo, JsonObjectsWithIdAndCoordinatesLikeTheFemurLandmarks) {
  const auto r = read_points("landmarks.json",
                             R"([{"coordinates": [1, 2, 3], "id": "L0"},
                                 {"id": "L1", "coordinates": [4.5, 5, 6]}])");
  ASSERT_TRUE(r.ok()) << r.error;
  ASSERT_EQ(r.list->points.rows(), 2);
  EXPECT_EQ(r.list->points.row(1), Eigen::RowVector3d(4.5, 5, 6));
  EXPECT_EQ(r.list->labels, (std::vector<std::string>{"L0", "L1"}));
}

TEST(PointListIo, JsonErrorsHaveLineAndColumn) {
  // points[2] starts at line 4, column 3.
  expect_error(read_points("m.json", "{\"points\": [\n  [1, 2, 3],\n  [4, 5, 6],\n  [7, 8]\n]}\n"),
               "m.json:4:3: ", "points[2]: expected 3 numbers [x, y, z], found 2");
  expect_error(read_points("n.json", "[[1, 2, 3],\n [4, \"5\", 6]]"),
               "n.json:2:6: ", "[1][1]: must be a number");
  expect_error(read_points("o.json", "[[1, 2, 3],\n [4, 5 6]]"), "o.json:2:8: ", "invalid JSON");
  expect_error(read_points("p.json", "[[1, 2, 1e999]]"), "p.json:1:9: ", "invalid JSON");
  expect_error(read_points("q.json", "{\"coordinateSystem\": \"IJK\", \"points\": [[1,2,3]]}"),
               "q.json:1:22: ", "unsupported coordinate system 'IJK'");
  expect_error(read_points("r.json", "{\"pts\": []}"), "r.json:1:1: ", "expected \"points\"");
  expect_error(read_points("s.json", "[]"), "s.json:1:1: ", "no points");
}

// ---------------------------------------------------------------------------------------------
// 3D Slicer markups (.mrk.json)

std::string markup(const std::string& system_field, const std::string& control_points) {
  return "{\"type\": \"Fiducial\", " + system_field +
         "\"coordinateUnits\": \"mm\", \"controlPoints\": [" + control_points + "]}";
}

std::string markups_file(const std::string& markups) {
  return "{\"@schema\": \"https://raw.githubusercontent.com/slicer/slicer/master/Modules/Loadable/"
         "Markups/Resources/Schema/markups-schema-v1.0.3.json#\",\n\"markups\": [" +
         markups + "]}\n";
}

TEST(PointListIo, SlicerMarkupsLpsRasAndDefault) {
  const std::string cps =
      R"({"id": "1", "label": "F-1", "position": [-53.25, -73.5, 0.0], "positionStatus": "defined"},
         {"id": "2", "label": "F-2", "position": [49.75, -88.5, 1.0]},
         {"id": "3", "label": "F-3", "position": [0, 0, 0], "positionStatus": "undefined"})";
  for (const auto& [field, system] : std::vector<std::pair<std::string, CoordinateSystem>>{
           {"\"coordinateSystem\": \"LPS\", ", CoordinateSystem::lps},
           {"\"coordinateSystem\": \"RAS\", ", CoordinateSystem::ras},
           {"", CoordinateSystem::lps}}) {
    const auto r = read_points("F.mrk.json", markups_file(markup(field, cps)));
    ASSERT_TRUE(r.ok()) << r.error;
    EXPECT_EQ(r.list->coordinate_system, system) << field;
    EXPECT_EQ(r.skipped_points, 1);
    ASSERT_EQ(r.list->points.rows(), 2);
    EXPECT_EQ(r.list->points.row(0), Eigen::RowVector3d(-53.25, -73.5, 0.0));
    EXPECT_EQ(r.list->labels, (std::vector<std::string>{"F-1", "F-2"}));
  }
}

TEST(PointListIo, SlicerMarkupsInDifferentSystemsAreConvertedToTheFirst) {
  const auto r = read_points(
      "two.mrk.json",
      markups_file(
          markup("\"coordinateSystem\": \"RAS\", ", R"({"position": [1, 2, 3]})") + ", " +
          markup("\"coordinateSystem\": \"LPS\", ", R"({"id": "7", "position": [1, 2, 3]})")));
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.list->coordinate_system, CoordinateSystem::ras);
  ASSERT_EQ(r.list->points.rows(), 2);
  EXPECT_EQ(r.list->points.row(0), Eigen::RowVector3d(1, 2, 3));
  EXPECT_EQ(r.list->points.row(1), Eigen::RowVector3d(-1, -2, 3));
  EXPECT_EQ(r.list->labels, (std::vector<std::string>{"", "7"}));
}

TEST(PointListIo, SlicerMarkupsErrors) {
  expect_error(
      read_points("a.mrk.json", markups_file("{\"type\": \"Fiducial\", \"coordinateUnits\": "
                                             "\"um\", \"controlPoints\": []}")),
      "a.mrk.json:2:", "markups[0].coordinateUnits: only millimetres");
  expect_error(read_points("b.mrk.json", markups_file(markup("", "{\"position\": [1, 2]}"))),
               "b.mrk.json:2:", "markups[0].controlPoints[0].position: expected 3 numbers");
  expect_error(
      read_points("c.mrk.json", markups_file(markup("", R"({"positionStatus": "undefined"})"))),
      "c.mrk.json:2:", "no control point has a defined position");
}

// ---------------------------------------------------------------------------------------------
// 3D Slicer .fcsv

const char* kFcsvColumns =
    "# columns = id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID\n";

TEST(PointListIo, FcsvCoordinateSystems) {
  for (const auto& [value, system] :
       std::vector<std::pair<std::string, CoordinateSystem>>{{"LPS", CoordinateSystem::lps},
                                                             {"RAS", CoordinateSystem::ras},
                                                             {"0", CoordinateSystem::ras},
                                                             {"1", CoordinateSystem::lps}}) {
    const std::string text =
        "# Markups fiducial file version = 4.11\n# CoordinateSystem = " + value + "\n" +
        kFcsvColumns +
        "vtkMRMLMarkupsFiducialNode_0,1.29,-40.18,60.15,0,0,0,1,1,1,0,F-1,,\n"
        "vtkMRMLMarkupsFiducialNode_1,2.5,3.5,-4.5,0,0,0,1,1,1,0,\"a, b\","
        "\"desc\",vtkMRMLScalarVolumeNode1\n";
    const auto r = read_points("F.fcsv", text);
    ASSERT_TRUE(r.ok()) << r.error;
    EXPECT_EQ(r.list->coordinate_system, system) << value;
    ASSERT_EQ(r.list->points.rows(), 2);
    EXPECT_EQ(r.list->points.row(0), Eigen::RowVector3d(1.29, -40.18, 60.15));
    EXPECT_EQ(r.list->labels, (std::vector<std::string>{"F-1", "a, b"}));
  }
}

TEST(PointListIo, FcsvCustomColumnsAndMissingSystem) {
  const auto r = read_points("custom.FCSV", "# columns = label,z,y,x\nA,3,2,1\nB,6,5,4\n");
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.list->coordinate_system, CoordinateSystem::unspecified);
  EXPECT_EQ(r.list->points.row(0), Eigen::RowVector3d(1, 2, 3));
  EXPECT_EQ(r.list->points.row(1), Eigen::RowVector3d(4, 5, 6));
  EXPECT_EQ(r.list->labels, (std::vector<std::string>{"A", "B"}));
}

TEST(PointListIo, FcsvErrors) {
  expect_error(read_points("a.fcsv", "# CoordinateSystem = IJK\n" + std::string(kFcsvColumns)),
               "a.fcsv:1: ", "unsupported CoordinateSystem 'IJK'");
  expect_error(
      read_points("b.fcsv", std::string("# CoordinateSystem = LPS\n") + kFcsvColumns + "n0,1,2\n"),
      "b.fcsv:3: ", "expected at least 4 fields");
  expect_error(read_points("c.fcsv", std::string(kFcsvColumns) + "n0,1,2,inf,0,0,0,1,1,1,0,F,,\n"),
               "c.fcsv:2: ", "field 4 (z) is not finite");
  expect_error(read_points("d.fcsv", "# columns = id,x,y\n"), "d.fcsv:1: ", "no 'z' column");
}

// ---------------------------------------------------------------------------------------------
// Coordinate-system conversion

TEST(PointListIo, RasLpsConversionNegatesXAndY) {
  PointList list;
  list.points = points3();
  list.coordinate_system = CoordinateSystem::ras;
  std::string error;
  ASSERT_TRUE(convert_coordinate_system(list, CoordinateSystem::lps, &error)) << error;
  EXPECT_EQ(list.coordinate_system, CoordinateSystem::lps);
  EXPECT_EQ(list.points.col(0), -points3().col(0));
  EXPECT_EQ(list.points.col(1), -points3().col(1));
  EXPECT_EQ(list.points.col(2), points3().col(2));
  ASSERT_TRUE(convert_coordinate_system(list, CoordinateSystem::lps, &error));  // no-op
  ASSERT_TRUE(convert_coordinate_system(list, CoordinateSystem::ras, &error));
  EXPECT_EQ(list.points, points3());

  PointList unknown;
  unknown.points = points3();
  EXPECT_FALSE(convert_coordinate_system(unknown, CoordinateSystem::ras, &error));
  EXPECT_NE(error.find("unspecified"), std::string::npos) << error;
  EXPECT_EQ(unknown.points, points3());
  EXPECT_FALSE(convert_coordinate_system(list, CoordinateSystem::unspecified, &error));
}

TEST(PointListIo, SameLandmarkFromFcsvInRasAndMrkJsonInLpsAgrees) {
  auto ras = read_points("a.fcsv", std::string("# CoordinateSystem = RAS\n") + kFcsvColumns +
                                       "n0,10.5,-20.25,30,0,0,0,1,1,1,0,tip,,\n");
  auto lps =
      read_points("a.mrk.json",
                  markups_file(markup("", R"({"label": "tip", "position": [-10.5, 20.25, 30]})")));
  ASSERT_TRUE(ras.ok() && lps.ok()) << ras.error << lps.error;
  ASSERT_TRUE(convert_coordinate_system(*lps.list, CoordinateSystem::ras));
  EXPECT_EQ(ras.list->points, lps.list->points);
}

// ---------------------------------------------------------------------------------------------
// Pairs

TEST(PointListIoPairs, JsonArrayAndObject) {
  const std::string pairs =
      R"([{"template": [1, 2, 3], "target": [4, 5, 6.5], "label": "apex"},
          {"template": [0.1, 0.2, 0.3], "target": [-1, -2, -3]}])";
  for (const std::string& text : {pairs, "{\"pairs\": " + pairs + "}"}) {
    const auto r = read_pairs("pairs.json", text);
    ASSERT_TRUE(r.ok()) << r.error;
    ASSERT_EQ(r.pairs->template_points.rows(), 2);
    EXPECT_EQ(r.pairs->template_points.row(1), Eigen::RowVector3d(0.1, 0.2, 0.3));
    EXPECT_EQ(r.pairs->target_points.row(0), Eigen::RowVector3d(4, 5, 6.5));
    EXPECT_EQ(r.pairs->labels, (std::vector<std::string>{"apex", ""}));
  }
}

TEST(PointListIoPairs, CsvWithAndWithoutLabel) {
  const Eigen::MatrixXd p = points3();
  auto r = read_pairs("pairs.csv", "tx,ty,tz,x,y,z\n" + row(p, 0, ",") + "," + row(p, 1, ",") +
                                       "\n" + row(p, 2, ",") + "," + row(p, 0, ",") + "\n");
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.pairs->template_points.row(0), p.row(0));
  EXPECT_EQ(r.pairs->target_points.row(0), p.row(1));
  EXPECT_EQ(r.pairs->target_points.row(1), p.row(0));
  EXPECT_TRUE(r.pairs->labels.empty());
  r = read_pairs("labelled.csv", "apex 1 2 3 4 5 6\nbase 7 8 9 10 11 12\n");
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.pairs->labels, (std::vector<std::string>{"apex", "base"}));
  EXPECT_EQ(r.pairs->target_points.row(1), Eigen::RowVector3d(10, 11, 12));
}

TEST(PointListIoPairs, Errors) {
  expect_error(read_pairs("a.json", "[{\"template\": [1, 2, 3],\n  \"traget\": [4, 5, 6]}]"),
               "a.json:2:13: ", "[0].traget: unknown key");
  expect_error(read_pairs("b.json", "[{\"template\": [1, 2, 3]}]"),
               "b.json:1:2: ", "[0]: has no \"target\"");
  expect_error(read_pairs("c.csv", "1,2,3,4,5,6\n1,2,3,4,5\n"),
               "c.csv:2: ", "expected 6 numbers, found 5");
  expect_error(read_pairs("d.csv", "1,2,3,4,5,nan\n"), "d.csv:1: ", "field 6 (z) is not finite");
  expect_error(read_pairs("e.json", "[]"), "e.json:1:1: ", "no pairs");
}

// ---------------------------------------------------------------------------------------------
// Real landmarks from ../shared/data (skipped when absent)

TEST(PointListIoRealData, FemurPairLandmarks) {
  const fs::path path = fs::path(SINEW_SHARED_DIR) / "data" / "femur_pair" / "femur_reference.json";
  if (!fs::exists(path)) GTEST_SKIP() << path << " not found (../shared is absent)";
  const auto r = read_point_list(path.string());
  ASSERT_TRUE(r.ok()) << r.error;
  ASSERT_EQ(r.list->points.rows(), 6);
  EXPECT_EQ(r.list->labels, (std::vector<std::string>{"L0", "L1", "L2", "L3", "L4", "L5"}));
  EXPECT_EQ(r.list->points(0, 0), -39.55951690673828);
  EXPECT_EQ(r.list->coordinate_system, CoordinateSystem::unspecified);
}

}  // namespace
