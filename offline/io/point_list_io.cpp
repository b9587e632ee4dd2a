#include "offline/io/point_list_io.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <exception>
#include <filesystem>
#include <new>
#include <utility>

#include "common/detail/json_error.hpp"
#include "offline/io/io_common.hpp"

namespace sinew::offline::io {
namespace {

using detail::fail;
using detail::fail_line;
using detail::parse_double;
using detail::quote_token;
using detail::ReadError;
using Json = nlohmann::json;

/// Points as they are read, before they become Eigen matrices.
struct RawPoints {
  std::vector<std::array<double, 3>> points;
  std::vector<std::string> labels;
  bool has_labels = false;
  CoordinateSystem system = CoordinateSystem::unspecified;
  int skipped = 0;
};

PointList to_point_list(const std::string& path, RawPoints raw) {
  if (raw.points.empty()) fail(path + ": no points");
  PointList list;
  list.points.resize(static_cast<Eigen::Index>(raw.points.size()), 3);
  for (std::size_t i = 0; i < raw.points.size(); ++i)
    for (int a = 0; a < 3; ++a)
      list.points(static_cast<Eigen::Index>(i), a) = raw.points[i][static_cast<std::size_t>(a)];
  if (raw.has_labels) list.labels = std::move(raw.labels);
  list.coordinate_system = raw.system;
  return list;
}

void flip_ras_lps(std::array<double, 3>& p) {
  p[0] = -p[0];
  p[1] = -p[1];
}

// ---------------------------------------------------------------------------------------------
// CSV-like text

struct Row {
  int line = 0;
  std::vector<std::string> fields;
};

/// Splits a comma-separated line; fields may be double-quoted ("" is a quote), spaces trimmed.
std::vector<std::string> split_commas(const std::string& file, int line, std::string_view text) {
  std::vector<std::string> fields;
  std::string field;
  bool quoted_field = false, in_quotes = false;
  for (std::size_t i = 0; i <= text.size(); ++i) {
    const char c = i < text.size() ? text[i] : ',';
    if (in_quotes) {
      if (i == text.size()) fail_line(file, line, "unterminated double quote");
      if (c == '"' && i + 1 < text.size() && text[i + 1] == '"') {
        field += '"';
        ++i;
      } else if (c == '"') {
        in_quotes = false;
      } else {
        field += c;
      }
    } else if (c == ',') {
      fields.push_back(quoted_field ? field : std::string(detail::trim(field)));
      field.clear();
      quoted_field = false;
    } else if (c == '"' && detail::trim(field).empty()) {
      field.clear();
      in_quotes = quoted_field = true;
    } else if (!(quoted_field && (c == ' ' || c == '\t'))) {
      field += c;
    }
  }
  return fields;
}

/// The data lines of a CSV-like file: blank lines and '#' comment lines are passed to
/// `on_comment` (fcsv headers) or skipped.
template <class OnComment>
std::vector<Row> read_rows(const std::string& path, const std::string& text, bool force_commas,
                           const OnComment& on_comment) {
  std::vector<Row> rows;
  int separator = force_commas ? 1 : -1;  // -1 undecided, 0 whitespace, 1 comma
  const auto lines = detail::split_lines(text);
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const int number = static_cast<int>(i) + 1;
    const std::string_view line = detail::trim(lines[i]);
    if (line.empty()) continue;
    if (line.front() == '#') {
      on_comment(number, line);
      continue;
    }
    if (separator < 0) separator = line.find(',') != std::string_view::npos ? 1 : 0;
    Row row;
    row.line = number;
    if (separator == 1) {
      row.fields = split_commas(path, number, line);
    } else {
      for (const auto t : detail::split_whitespace(line)) row.fields.emplace_back(t);
    }
    rows.push_back(std::move(row));
  }
  return rows;
}

bool all_numbers(const std::vector<std::string>& fields, std::size_t first) {
  double v = 0;
  for (std::size_t i = first; i < fields.size(); ++i) {
    if (!parse_double(fields[i], v)) return false;
  }
  return true;
}

/// A finite number from field i of a row; `name` is the column name for messages.
double field_number(const std::string& path, const Row& row, std::size_t i, const char* name) {
  const std::string& f = row.fields[i];
  double v = 0;
  const std::string which = "field " + std::to_string(i + 1) + " (" + name + ")";
  if (f.empty()) fail_line(path, row.line, which + " is empty, expected a number");
  if (!parse_double(f, v))
    fail_line(path, row.line, which + ": expected a number, got " + quote_token(f));
  if (!std::isfinite(v)) fail_line(path, row.line, which + " is not finite: " + quote_token(f));
  return v;
}

/// Rows of `numbers` numeric columns, optionally after one label column (see the header file).
/// Returns the rows (header removed) and whether they have a label column.
std::pair<std::vector<Row>, bool> numeric_rows(const std::string& path, const std::string& text,
                                               std::size_t numbers) {
  auto rows = read_rows(path, text, false, [](int, std::string_view) {});
  if (!rows.empty()) {
    // A header has a non-number among its last `numbers` fields ("x,y,z", "label,x,y,z").
    const auto& first = rows.front().fields;
    const std::size_t tail = first.size() >= numbers ? first.size() - numbers : 0;
    if (!all_numbers(first, tail)) rows.erase(rows.begin());
  }
  if (rows.empty()) fail(path + ": no points");
  const std::size_t n = rows.front().fields.size();
  const std::string expectation = std::to_string(numbers) + " numbers";
  if (n != numbers && n != numbers + 1)
    fail_line(path, rows.front().line,
              "expected " + expectation + " or a label and " + expectation + ", found " +
                  std::to_string(n) + " fields");
  const bool labelled = n == numbers + 1;
  for (const auto& row : rows) {
    if (row.fields.size() == n) continue;
    if (labelled)
      fail_line(path, row.line,
                "expected a label and " + expectation + " (like line " +
                    std::to_string(rows.front().line) + "), found " +
                    std::to_string(row.fields.size()) + " fields");
    fail_line(path, row.line,
              "expected " + expectation + ", found " + std::to_string(row.fields.size()));
  }
  return {std::move(rows), labelled};
}

RawPoints read_csv_points(const std::string& path, const std::string& text) {
  const auto [rows, labelled] = numeric_rows(path, text, 3);
  RawPoints raw;
  raw.has_labels = labelled;
  const std::size_t first = labelled ? 1 : 0;
  for (const auto& row : rows) {
    raw.points.push_back({field_number(path, row, first, "x"),
                          field_number(path, row, first + 1, "y"),
                          field_number(path, row, first + 2, "z")});
    raw.labels.push_back(labelled ? row.fields[0] : std::string());
  }
  return raw;
}

// ---------------------------------------------------------------------------------------------
// Slicer .fcsv

CoordinateSystem parse_system_name(const std::string& value, bool allow_numbers) {
  const std::string v = detail::to_lower(value);
  if (v == "ras" || (allow_numbers && v == "0")) return CoordinateSystem::ras;
  if (v == "lps" || (allow_numbers && v == "1")) return CoordinateSystem::lps;
  return CoordinateSystem::unspecified;
}

RawPoints read_fcsv(const std::string& path, const std::string& text) {
  RawPoints raw;
  std::vector<std::string> columns = {
      "id", "x",   "y",   "z",    "ow",    "ox",   "oy",
      "oz", "vis", "sel", "lock", "label", "desc", "associatedNodeID"};
  int columns_line = 0;
  const auto on_comment = [&](int line, std::string_view comment) {
    const std::string_view body = detail::trim(comment.substr(1));
    const auto eq = body.find('=');
    if (eq == std::string_view::npos) return;
    const std::string key = detail::to_lower(std::string(detail::trim(body.substr(0, eq))));
    const std::string value(detail::trim(body.substr(eq + 1)));
    if (key == "coordinatesystem") {
      raw.system = parse_system_name(value, true);
      if (raw.system == CoordinateSystem::unspecified)
        fail_line(
            path, line,
            "unsupported CoordinateSystem " + quote_token(value) + " (expected RAS, LPS, 0 or 1)");
    } else if (key == "columns") {
      columns = split_commas(path, line, value);
      columns_line = line;
    }
  };
  const auto rows = read_rows(path, text, true, on_comment);
  const auto column = [&](const char* name, bool required) -> std::size_t {
    for (std::size_t i = 0; i < columns.size(); ++i) {
      if (detail::to_lower(columns[i]) == name) return i;
    }
    if (required)
      fail_line(path, columns_line, std::string("the columns line has no '") + name + "' column");
    return columns.size();
  };
  const std::size_t ix = column("x", true), iy = column("y", true), iz = column("z", true);
  const std::size_t il = column("label", false);
  raw.has_labels = il < columns.size();
  for (const auto& row : rows) {
    const std::size_t needed = std::max({ix, iy, iz}) + 1;
    if (row.fields.size() < needed)
      fail_line(path, row.line,
                "expected at least " + std::to_string(needed) + " fields (x, y, z are columns " +
                    std::to_string(ix + 1) + ", " + std::to_string(iy + 1) + ", " +
                    std::to_string(iz + 1) + "), found " + std::to_string(row.fields.size()));
    raw.points.push_back({field_number(path, row, ix, "x"), field_number(path, row, iy, "y"),
                          field_number(path, row, iz, "z")});
    raw.labels.push_back(raw.has_labels && il < row.fields.size() ? row.fields[il] : std::string());
  }
  return raw;
}

// ---------------------------------------------------------------------------------------------
// JSON with line:column positions for every message

/// The parsed document with its text, to turn a JSON path into line:column.
struct JsonDocument {
  std::string file;
  std::string text;
  Json root;
};

JsonDocument read_json(const std::string& path) {
  JsonDocument doc;
  doc.file = path;
  doc.text = detail::read_whole_file(path);
  try {
    doc.root = Json::parse(doc.text);
  } catch (const Json::parse_error& e) {
    fail(common::detail::json_syntax_error(path, doc.text, e.what(), e.byte));
  } catch (const Json::exception& e) {
    fail(common::detail::json_value_error(path, doc.text, e.what()));
  }
  return doc;
}

/// A value inside a JsonDocument that knows its path, for "file:line:col: path what".
class Node {
 public:
  Node(const JsonDocument& doc, const Json& value, std::vector<common::detail::JsonPathStep> path)
      : doc_(&doc), value_(&value), path_(std::move(path)) {}

  const Json& value() const { return *value_; }
  bool has(const std::string& key) const { return value_->is_object() && value_->contains(key); }
  Node at(const std::string& key) const {
    auto p = path_;
    p.push_back({true, key, 0});
    return Node(*doc_, value_->at(key), std::move(p));
  }
  Node at(std::size_t i) const {
    auto p = path_;
    p.push_back({false, std::string(), i});
    return Node(*doc_, (*value_)[i], std::move(p));
  }
  std::string name() const {
    std::string s;
    for (const auto& step : path_) {
      if (step.is_key)
        s += (s.empty() ? "" : ".") + step.key;
      else
        s += "[" + std::to_string(step.index) + "]";
    }
    return s.empty() ? "document" : s;
  }
  [[noreturn]] void fail_here(const std::string& what) const {
    const std::size_t offset = common::detail::JsonLocator(doc_->text).find(path_);
    fail(doc_->file + ":" + common::detail::line_column(doc_->text, offset) + ": " + name() + ": " +
         what);
  }
  std::string string() const {
    if (!value_->is_string()) fail_here("must be a string");
    return value_->get<std::string>();
  }
  const Json& array() const {
    if (!value_->is_array()) fail_here("must be an array");
    return *value_;
  }
  /// A finite [x, y, z].
  std::array<double, 3> point() const {
    if (!value_->is_array()) fail_here("expected an array [x, y, z]");
    if (value_->size() != 3)
      fail_here("expected 3 numbers [x, y, z], found " + std::to_string(value_->size()));
    std::array<double, 3> p{};
    for (std::size_t a = 0; a < 3; ++a) {
      const Node c = at(a);
      if (!c.value().is_number()) c.fail_here("must be a number");
      p[a] = c.value().get<double>();
      if (!std::isfinite(p[a])) c.fail_here("must be a finite number");
    }
    return p;
  }
  void expect_keys(const std::vector<std::string>& allowed) const {
    for (const auto& item : value_->items()) {
      if (std::find(allowed.begin(), allowed.end(), item.key()) != allowed.end()) continue;
      std::string list;
      for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
      at(item.key()).fail_here("unknown key (expected one of: " + list + ")");
    }
  }

 private:
  const JsonDocument* doc_;
  const Json* value_;
  std::vector<common::detail::JsonPathStep> path_;
};

CoordinateSystem json_system(const Node& node) {
  const std::string name = node.string();
  const CoordinateSystem s = parse_system_name(name, false);
  if (s == CoordinateSystem::unspecified)
    node.fail_here("unsupported coordinate system " + quote_token(name) +
                   " (expected \"RAS\" or \"LPS\")");
  return s;
}

/// Elements [x, y, z] or {"position"|"coordinates": [x, y, z], "label"|"id"|"name": "..."}.
void read_json_point_array(const Node& array, RawPoints& raw) {
  const std::size_t n = array.array().size();
  for (std::size_t i = 0; i < n; ++i) {
    const Node e = array.at(i);
    if (e.value().is_object()) {
      const char* position_key = e.has("position") ? "position" : "coordinates";
      if (!e.has(position_key)) e.fail_here("has no \"position\" or \"coordinates\"");
      raw.points.push_back(e.at(position_key).point());
      std::string label;
      for (const char* key : {"label", "id", "name"}) {
        if (e.has(key)) {
          label = e.at(key).string();
          raw.has_labels = true;
          break;
        }
      }
      raw.labels.push_back(label);
    } else {
      raw.points.push_back(e.point());
      raw.labels.emplace_back();
    }
  }
}

RawPoints read_slicer_markups(const Node& root) {
  RawPoints raw;
  raw.has_labels = true;
  const Node markups = root.at("markups");
  const std::size_t n = markups.array().size();
  bool first_system = true;
  for (std::size_t m = 0; m < n; ++m) {
    const Node markup = markups.at(m);
    if (!markup.value().is_object()) markup.fail_here("must be an object");
    CoordinateSystem system = CoordinateSystem::lps;  // the schema's default
    if (markup.has("coordinateSystem")) system = json_system(markup.at("coordinateSystem"));
    if (markup.has("coordinateUnits")) {
      const Node units = markup.at("coordinateUnits");
      const bool mm =
          (units.value().is_string() && units.value() == "mm") ||
          (units.value().is_array() && !units.value().empty() && units.value()[0] == "mm");
      if (!mm) units.fail_here("only millimetres (\"mm\") are supported");
    }
    if (first_system) {
      raw.system = system;
      first_system = false;
    }
    if (!markup.has("controlPoints")) continue;
    const Node points = markup.at("controlPoints");
    const std::size_t np = points.array().size();
    for (std::size_t i = 0; i < np; ++i) {
      const Node cp = points.at(i);
      if (!cp.value().is_object()) cp.fail_here("must be an object");
      if (cp.has("positionStatus")) {
        const std::string status = cp.at("positionStatus").string();
        if (status == "undefined" || status == "preview") {
          ++raw.skipped;
          continue;
        }
        if (status != "defined")
          cp.at("positionStatus")
              .fail_here("unknown status " + quote_token(status) +
                         " (expected \"defined\", \"preview\" or \"undefined\")");
      }
      if (!cp.has("position")) cp.fail_here("has no \"position\"");
      auto p = cp.at("position").point();
      if (system != raw.system) flip_ras_lps(p);
      raw.points.push_back(p);
      raw.labels.push_back(cp.has("label") ? cp.at("label").string()
                                           : (cp.has("id") ? cp.at("id").string() : ""));
    }
  }
  if (raw.points.empty())
    root.at("markups").fail_here(raw.skipped > 0 ? "no control point has a defined position"
                                                 : "no control points");
  return raw;
}

RawPoints read_json_points(const std::string& path) {
  const JsonDocument doc = read_json(path);
  const Node root(doc, doc.root, {});
  if (root.value().is_array()) {
    RawPoints raw;
    read_json_point_array(root, raw);
    if (raw.points.empty()) root.fail_here("no points");
    return raw;
  }
  if (!root.value().is_object())
    root.fail_here("expected an array of points, an object with \"points\", or Slicer markups");
  if (root.has("markups")) return read_slicer_markups(root);
  if (!root.has("points"))
    root.fail_here("expected \"points\" (or \"markups\" for a Slicer markups file)");
  RawPoints raw;
  if (root.has("coordinateSystem")) raw.system = json_system(root.at("coordinateSystem"));
  read_json_point_array(root.at("points"), raw);
  if (raw.points.empty()) root.at("points").fail_here("no points");
  return raw;
}

// ---------------------------------------------------------------------------------------------
// Pairs

struct RawPairs {
  std::vector<std::array<double, 3>> from, to;
  std::vector<std::string> labels;
  bool has_labels = false;
};

RawPairs read_json_pairs(const std::string& path) {
  const JsonDocument doc = read_json(path);
  const Node root(doc, doc.root, {});
  Node array = root;
  if (root.value().is_object()) {
    root.expect_keys({"pairs"});
    if (!root.has("pairs")) root.fail_here("expected \"pairs\"");
    array = root.at("pairs");
  } else if (!root.value().is_array()) {
    root.fail_here("expected an array of {\"template\": [x, y, z], \"target\": [x, y, z]}");
  }
  RawPairs raw;
  const std::size_t n = array.array().size();
  if (n == 0) array.fail_here("no pairs");
  for (std::size_t i = 0; i < n; ++i) {
    const Node e = array.at(i);
    if (!e.value().is_object())
      e.fail_here("expected an object {\"template\": [x, y, z], \"target\": [x, y, z]}");
    e.expect_keys({"template", "target", "label"});
    if (!e.has("template")) e.fail_here("has no \"template\"");
    if (!e.has("target")) e.fail_here("has no \"target\"");
    raw.from.push_back(e.at("template").point());
    raw.to.push_back(e.at("target").point());
    raw.has_labels = raw.has_labels || e.has("label");
    raw.labels.push_back(e.has("label") ? e.at("label").string() : std::string());
  }
  return raw;
}

RawPairs read_csv_pairs(const std::string& path, const std::string& text) {
  const auto [rows, labelled] = numeric_rows(path, text, 6);
  RawPairs raw;
  raw.has_labels = labelled;
  const std::size_t f = labelled ? 1 : 0;
  for (const auto& row : rows) {
    raw.from.push_back({field_number(path, row, f, "tx"), field_number(path, row, f + 1, "ty"),
                        field_number(path, row, f + 2, "tz")});
    raw.to.push_back({field_number(path, row, f + 3, "x"), field_number(path, row, f + 4, "y"),
                      field_number(path, row, f + 5, "z")});
    raw.labels.push_back(labelled ? row.fields[0] : std::string());
  }
  return raw;
}

Eigen::MatrixXd to_matrix(const std::vector<std::array<double, 3>>& points) {
  Eigen::MatrixXd m(static_cast<Eigen::Index>(points.size()), 3);
  for (std::size_t i = 0; i < points.size(); ++i)
    m.row(static_cast<Eigen::Index>(i)) << points[i][0], points[i][1], points[i][2];
  return m;
}

enum class Kind { csv, json, fcsv, unknown };

Kind kind_of(const std::string& path) {
  if (detail::ends_with_ci(path, ".fcsv")) return Kind::fcsv;
  if (detail::ends_with_ci(path, ".json")) return Kind::json;
  if (detail::ends_with_ci(path, ".csv") || detail::ends_with_ci(path, ".txt")) return Kind::csv;
  return Kind::unknown;
}

}  // namespace

const char* to_string(CoordinateSystem system) {
  switch (system) {
    case CoordinateSystem::ras:
      return "RAS";
    case CoordinateSystem::lps:
      return "LPS";
    case CoordinateSystem::unspecified:
      break;
  }
  return "unspecified";
}

PointListReadResult read_point_list(const std::string& path) {
  return detail::guarded_read<PointListReadResult>(path, [&] {
    RawPoints raw;
    switch (kind_of(path)) {
      case Kind::csv:
        raw = read_csv_points(path, detail::read_whole_file(path));
        break;
      case Kind::fcsv:
        raw = read_fcsv(path, detail::read_whole_file(path));
        break;
      case Kind::json:
        raw = read_json_points(path);
        break;
      case Kind::unknown:
        fail(path + ": unknown point-list extension " +
             quote_token(std::filesystem::path(path).extension().string()) +
             " (expected .csv, .txt, .json, .mrk.json or .fcsv)");
    }
    PointListReadResult result;
    result.skipped_points = raw.skipped;
    result.list = to_point_list(path, std::move(raw));
    return result;
  });
}

bool convert_coordinate_system(PointList& list, CoordinateSystem target, std::string* error) {
  const auto failed = [&](const std::string& what) {
    if (error != nullptr) *error = what;
    return false;
  };
  if (target == CoordinateSystem::unspecified)
    return failed("cannot convert points to an unspecified coordinate system");
  if (list.coordinate_system == CoordinateSystem::unspecified)
    return failed(std::string("cannot convert points to ") + to_string(target) +
                  ": their coordinate system is unspecified (the file does not state it)");
  if (list.coordinate_system != target) {
    list.points.col(0) *= -1.0;
    list.points.col(1) *= -1.0;
    list.coordinate_system = target;
  }
  return true;
}

PointPairsReadResult read_point_pairs(const std::string& path) {
  return detail::guarded_read<PointPairsReadResult>(path, [&] {
    RawPairs raw;
    switch (kind_of(path)) {
      case Kind::csv:
        raw = read_csv_pairs(path, detail::read_whole_file(path));
        break;
      case Kind::json:
        raw = read_json_pairs(path);
        break;
      case Kind::fcsv:
      case Kind::unknown:
        fail(path + ": unknown point-pair extension " +
             quote_token(std::filesystem::path(path).extension().string()) +
             " (expected .csv, .txt or .json)");
    }
    if (raw.from.empty()) fail(path + ": no pairs");
    PointPairs pairs;
    pairs.template_points = to_matrix(raw.from);
    pairs.target_points = to_matrix(raw.to);
    if (raw.has_labels) pairs.labels = std::move(raw.labels);
    PointPairsReadResult result;
    result.pairs = std::move(pairs);
    return result;
  });
}

}  // namespace sinew::offline::io
