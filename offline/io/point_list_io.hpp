#pragma once
/// Marker (landmark) readers for the registration case file: lists of 3D points, and pairs of a
/// point on the template and its position in the target scan.
///
/// Errors are never thrown: every failure is ONE line "file:line: what is wrong" (text formats),
/// "file:line:col: where what is wrong" (JSON; `where` is the JSON path, e.g. points[2]), or
/// "file: what is wrong" when no position applies, e.g.
///   markers.csv:7: expected 3 numbers, found 2
///   markers.json:5:4: points[2]: expected 3 numbers [x, y, z], found 2
/// Non-finite values are errors; an empty list is an error.
///
/// Coordinate systems. Medical images name their axes by the patient direction they increase
/// towards: RAS = x to the patient's Right, y Anterior, z Superior (3D Slicer's internal world
/// frame, NIfTI scanner space); LPS = x Left, y Posterior, z Superior (DICOM, ITK, and Slicer's
/// files since 4.11). The same physical point has (x, y, z) in RAS and (-x, -y, z) in LPS.

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

namespace sinew::offline::io {

enum class CoordinateSystem {
  unspecified,  ///< the file does not say (CSV, plain JSON without "coordinateSystem")
  ras,          ///< x Right, y Anterior, z Superior
  lps,          ///< x Left, y Posterior, z Superior
};

/// "unspecified", "RAS" or "LPS".
const char* to_string(CoordinateSystem system);

struct PointList {
  Eigen::MatrixXd points;           ///< #P by 3, file units (Slicer: millimetres)
  std::vector<std::string> labels;  ///< one per point (maybe ""), or empty when the file has none
  CoordinateSystem coordinate_system = CoordinateSystem::unspecified;
};

struct PointListReadResult {
  std::optional<PointList> list;  ///< set on success
  std::string error;              ///< one line on failure, empty on success
  /// .mrk.json only: control points skipped because their positionStatus is "undefined" or
  /// "preview" (placed-but-unset points have no meaningful position).
  int skipped_points = 0;
  bool ok() const { return list.has_value(); }
};

/// Reads a point list, dispatching on the extension (case-insensitive):
///
/// `.csv`, `.txt`: one point per row. Lines that are blank or whose first non-blank character is
///   '#' are skipped. The separator is decided by the first non-skipped line: if it contains a
///   comma, fields are comma-separated (a field may be double-quoted, "" is a quote inside it;
///   spaces around fields are trimmed); otherwise fields are separated by spaces/tabs. The first
///   non-skipped line is a header (and is skipped) if any of its last 3 fields is not a number. The
///   first data row fixes the layout for the whole file: 3 fields = x,y,z; 4 fields =
///   label,x,y,z (the label may be any text, also a number); anything else is an error. Labels
///   are returned only in the 4-field layout. Coordinate system: unspecified.
///
/// `.json` (also `.mrk.json`), by content:
///   - an array whose elements are [x, y, z] or objects with "position" or "coordinates" (an
///     [x, y, z]) and an optional "label", "id" or "name" string (e.g. [{"id": "L0",
///     "coordinates": [1, 2, 3]}]);
///   - an object with such a "points" array and an optional "coordinateSystem" ("RAS"/"LPS");
///   - a 3D Slicer markups file: an object with "markups": every markup's controlPoints[*]
///     .position, label from "label" (else "id"); "coordinateSystem" per markup, "LPS" when
///     absent (the schema's default); markups in different systems are converted to the first
///     one's. Control points with positionStatus "undefined" or "preview" are skipped (counted).
///     "coordinateUnits" other than "mm" is an error.
///
/// `.fcsv` (3D Slicer fiducial list): comment lines "# CoordinateSystem = X" with X = RAS or 0
///   (RAS), LPS or 1 (LPS), and "# columns = id,x,y,z,...,label,..." locate the values; without a
///   columns line the Slicer order id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID
///   is assumed. Rows are comma-separated (double quotes as in CSV). Labels from the "label"
///   column. Without a CoordinateSystem line the system is unspecified (old Slicer versions
///   wrote RAS; the caller must decide).
PointListReadResult read_point_list(const std::string& path);

/// Converts the points in place to `target`: RAS <-> LPS negates x and y, z is unchanged; a no-op
/// when the systems are equal. Fails (returns false, sets *error, leaves the list unchanged) when
/// `target` or the list's system is unspecified (set PointList::coordinate_system first when the
/// caller knows it).
bool convert_coordinate_system(PointList& list, CoordinateSystem target,
                               std::string* error = nullptr);

/// Corresponding points: template_points.row(i) on the template surface should move to
/// target_points.row(i) in the scan.
struct PointPairs {
  Eigen::MatrixXd template_points;  ///< #P by 3
  Eigen::MatrixXd target_points;    ///< #P by 3
  std::vector<std::string> labels;  ///< one per pair (maybe ""), or empty when none are given
};

struct PointPairsReadResult {
  std::optional<PointPairs> pairs;  ///< set on success
  std::string error;                ///< one line on failure, empty on success
  bool ok() const { return pairs.has_value(); }
};

/// Reads point pairs, dispatching on the extension (case-insensitive):
/// `.json`: an array of objects {"template": [x, y, z], "target": [x, y, z], "label": "..."
///   (optional)}, or an object with such a "pairs" array. Other keys are errors (typos).
/// `.csv`, `.txt`: rules as for point lists, with 6 numbers tx,ty,tz,x,y,z (template, then target)
///   or 7 fields label,tx,ty,tz,x,y,z; a header is detected by a non-number in its last 6 fields.
PointPairsReadResult read_point_pairs(const std::string& path);

}  // namespace sinew::offline::io
