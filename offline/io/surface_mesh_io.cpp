#include "offline/io/surface_mesh_io.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <exception>
#include <filesystem>
#include <new>
#include <sstream>
#include <unordered_map>
#include <utility>
#include <vector>

#include "offline/io/io_common.hpp"

namespace sinew::offline::io {
namespace {

using detail::fail;
using detail::fail_line;
using detail::number;
using detail::parse_double;
using detail::parse_integer;
using detail::quote_token;
using detail::ReadError;

/// What the format parsers produce: vertices and polygons as read, each polygon with the place
/// it came from (a line number for text formats, a byte offset for binary ones).
struct RawSurface {
  std::string file;
  bool binary = false;
  std::vector<double> xyz;                 ///< 3 per vertex
  std::vector<long long> corners;          ///< 0-based vertex indices (maybe out of range)
  std::vector<std::size_t> face_start{0};  ///< face f owns corners[face_start[f], face_start[f+1])
  std::vector<long long> face_where;       ///< line number or byte offset of face f
  int merged_stl_corners = 0;
  int index_base = 0;  ///< numbering of the file (OBJ: 1), for messages

  std::size_t vertex_count() const { return xyz.size() / 3; }
  std::size_t face_count() const { return face_where.size(); }

  /// "file:line: " or "file: byte N: face f " prefix for a message about face f.
  std::string at_face(std::size_t f) const {
    if (binary)
      return file + ": byte " + std::to_string(face_where[f]) + ": face " + std::to_string(f) + " ";
    return file + ":" + std::to_string(face_where[f]) + ": face ";
  }
  void end_face(long long where) {
    face_start.push_back(corners.size());
    face_where.push_back(where);
  }
};

/// Checks a vertex is finite; `where` builds the message prefix only on failure.
template <class Where>
void add_vertex(RawSurface& raw, double x, double y, double z, const Where& where) {
  if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z))
    fail(where() + "has a non-finite coordinate (" + number(x) + " " + number(y) + " " + number(z) +
         ")");
  raw.xyz.insert(raw.xyz.end(), {x, y, z});
}

// ---------------------------------------------------------------------------------------------
// Token streams for OFF and ASCII PLY: tokens with their line numbers, '#' comments removed.

struct Token {
  std::string_view text;
  int line = 0;
};

class TokenStream {
 public:
  TokenStream(const std::string& file, std::string_view text, int first_line, bool hash_comments)
      : file_(file) {
    const auto lines = detail::split_lines(text);
    last_line_ = first_line + static_cast<int>(lines.size()) - 1;
    if (last_line_ < first_line) last_line_ = first_line;
    for (std::size_t i = 0; i < lines.size(); ++i) {
      std::string_view line = lines[i];
      if (hash_comments) {
        if (const auto hash = line.find('#'); hash != std::string_view::npos)
          line = line.substr(0, hash);
      }
      for (const auto t : detail::split_whitespace(line))
        tokens_.push_back({t, first_line + static_cast<int>(i)});
    }
  }

  bool at_end() const { return next_ >= tokens_.size(); }
  const Token& peek() const { return tokens_[next_]; }
  /// The next token; fails with "file:last_line: file ends before <what> (truncated file?)".
  const Token& take(const std::string& what) {
    if (at_end()) fail_line(file_, last_line_, "file ends before " + what + " (truncated file?)");
    return tokens_[next_++];
  }
  /// Skips the rest of `line` (trailing colours, normals).
  void skip_line(int line) {
    while (!at_end() && tokens_[next_].line == line) ++next_;
  }
  double real(const std::string& what) {
    const Token& t = take(what);
    double v = 0;
    if (!parse_double(t.text, v))
      fail_line(file_, t.line, "expected a number (" + what + "), got " + quote_token(t.text));
    return v;
  }
  long long integer(const std::string& what) {
    const Token& t = take(what);
    long long v = 0;
    if (!parse_integer(t.text, v))
      fail_line(file_, t.line, "expected an integer (" + what + "), got " + quote_token(t.text));
    return v;
  }
  int last_line() const { return last_line_; }

 private:
  std::string file_;
  std::vector<Token> tokens_;
  std::size_t next_ = 0;
  int last_line_ = 1;
};

/// A declared count that fits an int; `line` for the message.
int checked_count(const std::string& file, int line, long long n, const std::string& what) {
  if (n < 0 || n > INT32_MAX) fail_line(file, line, "invalid " + what + " " + std::to_string(n));
  return static_cast<int>(n);
}

constexpr std::size_t kReserveCap = 1 << 20;  // never trust a header with a huge allocation

void reserve(RawSurface& raw, long long vertices, long long faces) {
  raw.xyz.reserve(3 * std::min<std::size_t>(static_cast<std::size_t>(vertices), kReserveCap));
  raw.face_where.reserve(std::min<std::size_t>(static_cast<std::size_t>(faces), kReserveCap));
  raw.face_start.reserve(std::min<std::size_t>(static_cast<std::size_t>(faces), kReserveCap) + 1);
  raw.corners.reserve(3 * std::min<std::size_t>(static_cast<std::size_t>(faces), kReserveCap));
}

// ---------------------------------------------------------------------------------------------
// OBJ

RawSurface read_obj(const std::string& path, std::string_view text) {
  RawSurface raw;
  raw.file = path;
  raw.index_base = 1;
  const auto lines = detail::split_lines(text);
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const int line_number = static_cast<int>(i) + 1;
    std::string_view line = lines[i];
    if (const auto hash = line.find('#'); hash != std::string_view::npos)
      line = line.substr(0, hash);
    const auto tokens = detail::split_whitespace(line);
    if (tokens.empty()) continue;
    const auto at = [&] { return path + ":" + std::to_string(line_number) + ": "; };
    if (tokens[0] == "v") {
      if (tokens.size() < 4)
        fail_line(path, line_number,
                  "vertex: expected 3 numbers x y z, found " + std::to_string(tokens.size() - 1));
      double x[3];
      for (int a = 0; a < 3; ++a) {
        if (!parse_double(tokens[static_cast<std::size_t>(a) + 1], x[a]))
          fail_line(path, line_number,
                    "vertex: expected a number, got " +
                        quote_token(tokens[static_cast<std::size_t>(a) + 1]));
      }
      add_vertex(raw, x[0], x[1], x[2], [&] { return at() + "vertex "; });
    } else if (tokens[0] == "f") {
      if (tokens.size() < 4)
        fail_line(path, line_number,
                  "face has " + std::to_string(tokens.size() - 1) + " corners, at least 3 needed");
      const auto defined = static_cast<long long>(raw.vertex_count());
      for (std::size_t c = 1; c < tokens.size(); ++c) {
        const std::string_view corner = tokens[c];
        const std::string_view index_text = corner.substr(0, corner.find('/'));
        long long index = 0;
        if (!parse_integer(index_text, index))
          fail_line(path, line_number,
                    "face corner " + quote_token(corner) +
                        ": expected a vertex index (i, i/t, i//n "
                        "or i/t/n)");
        if (index == 0)
          fail_line(path, line_number, "face references vertex 0 (OBJ indices start at 1)");
        if (index < 0) {
          if (-index > defined)
            fail_line(path, line_number,
                      "face has relative index " + std::to_string(index) + ", but only " +
                          std::to_string(defined) + " vertices are defined before this line");
          raw.corners.push_back(defined + index);
        } else {
          raw.corners.push_back(index - 1);
        }
      }
      raw.end_face(line_number);
    }
    // vt, vn, vp, l, p, g, o, s, usemtl, mtllib and unknown statements are ignored.
  }
  return raw;
}

// ---------------------------------------------------------------------------------------------
// OFF

RawSurface read_off(const std::string& path, std::string_view text) {
  RawSurface raw;
  raw.file = path;
  TokenStream src(path, text, 1, true);
  const Token header = src.take("the 'OFF' header");
  {
    std::string h(header.text);
    std::size_t p = 0;
    if (h.compare(p, 2, "ST") == 0) p += 2;
    if (h.compare(p, 1, "C") == 0) p += 1;
    if (h.compare(p, 1, "N") == 0) p += 1;
    if (h.compare(p, 1, "4") == 0 || h.compare(p, 1, "n") == 0)
      fail_line(path, header.line,
                "header " + quote_token(h) + ": only 3D OFF files are supported");
    if (h.substr(p) != "OFF")
      fail_line(path, header.line, "expected the header 'OFF', got " + quote_token(h));
  }
  if (!src.at_end() && src.peek().line == header.line &&
      detail::to_lower(std::string(src.peek().text)) == "binary")
    fail_line(path, header.line, "binary OFF is not supported");
  const Token& nv_token = src.take("the vertex count");
  long long nv = 0, nf = 0;
  if (!parse_integer(nv_token.text, nv))
    fail_line(path, nv_token.line, "expected the vertex count, got " + quote_token(nv_token.text));
  const int counts_line = nv_token.line;
  nf = src.integer("the face count");
  checked_count(path, counts_line, nv, "vertex count");
  checked_count(path, counts_line, nf, "face count");
  src.skip_line(counts_line);  // the edge count (ignored)
  reserve(raw, nv, nf);
  for (long long i = 0; i < nv; ++i) {
    const std::string what = "vertex " + std::to_string(i) + " of " + std::to_string(nv);
    double x[3];
    int line = 0;
    for (double& xa : x) {
      if (!src.at_end()) line = src.peek().line;
      xa = src.real("a coordinate of " + what);
    }
    add_vertex(raw, x[0], x[1], x[2], [&] {
      return path + ":" + std::to_string(line) + ": vertex " + std::to_string(i) + " ";
    });
    src.skip_line(line);
  }
  for (long long f = 0; f < nf; ++f) {
    const std::string what = "face " + std::to_string(f) + " of " + std::to_string(nf);
    const Token& count_token = src.take(what);
    long long n = 0;
    if (!parse_integer(count_token.text, n))
      fail_line(path, count_token.line,
                "expected the corner count of " + what + ", got " + quote_token(count_token.text));
    if (n < 3)
      fail_line(path, count_token.line,
                "face has " + std::to_string(n) + " corners, at least 3 needed");
    for (long long c = 0; c < n; ++c)
      raw.corners.push_back(src.integer("a vertex index of " + what));
    raw.end_face(count_token.line);
    src.skip_line(count_token.line);  // per-face colour
  }
  if (!src.at_end())
    fail_line(path, src.peek().line,
              "unexpected " + quote_token(src.peek().text) + " after the " + std::to_string(nf) +
                  " faces declared at line " + std::to_string(counts_line));
  return raw;
}

// ---------------------------------------------------------------------------------------------
// STL

struct PositionKey {
  std::array<double, 3> x;
  bool operator==(const PositionKey& o) const { return x == o.x; }
};
struct PositionHash {
  std::size_t operator()(const PositionKey& k) const {
    std::size_t h = 0;
    for (const double v : k.x) {
      std::uint64_t bits = 0;
      std::memcpy(&bits, &v, sizeof bits);
      h ^= std::hash<std::uint64_t>{}(bits) + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2);
    }
    return h;
  }
};

/// Merges bitwise-equal STL corners (after mapping -0 to +0) into indexed vertices.
class VertexMerger {
 public:
  explicit VertexMerger(RawSurface& raw) : raw_(raw) {}
  long long index(double x, double y, double z) {
    const PositionKey key{{x + 0.0, y + 0.0, z + 0.0}};  // -0 + 0 = +0
    const auto [it, inserted] = map_.try_emplace(key, static_cast<long long>(raw_.vertex_count()));
    if (inserted)
      raw_.xyz.insert(raw_.xyz.end(), key.x.begin(), key.x.end());
    else
      ++raw_.merged_stl_corners;
    return it->second;
  }

 private:
  RawSurface& raw_;
  std::unordered_map<PositionKey, long long, PositionHash> map_;
};

std::uint32_t load_u32_le(const unsigned char* p) {
  return static_cast<std::uint32_t>(p[0]) | (static_cast<std::uint32_t>(p[1]) << 8) |
         (static_cast<std::uint32_t>(p[2]) << 16) | (static_cast<std::uint32_t>(p[3]) << 24);
}

float load_f32_le(const unsigned char* p) {
  const std::uint32_t bits = load_u32_le(p);
  float f = 0;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}

RawSurface read_stl_binary(const std::string& path, std::string_view bytes) {
  RawSurface raw;
  raw.file = path;
  raw.binary = true;
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
  const std::uint32_t n = load_u32_le(data + 80);
  reserve(raw, n / 2, n);
  VertexMerger merger(raw);
  for (std::uint32_t f = 0; f < n; ++f) {
    const std::size_t offset = 84 + 50 * static_cast<std::size_t>(f);
    const unsigned char* corner = data + offset + 12;
    for (int c = 0; c < 3; ++c, corner += 12) {
      const double x = load_f32_le(corner), y = load_f32_le(corner + 4),
                   z = load_f32_le(corner + 8);
      if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z))
        fail(path + ": byte " + std::to_string(offset + 12 + 12 * static_cast<std::size_t>(c)) +
             ": facet " + std::to_string(f) + " has a non-finite coordinate (" + number(x) + " " +
             number(y) + " " + number(z) + ")");
      raw.corners.push_back(merger.index(x, y, z));
    }
    raw.end_face(static_cast<long long>(offset));
  }
  return raw;
}

RawSurface read_stl_ascii(const std::string& path, std::string_view text) {
  RawSurface raw;
  raw.file = path;
  VertexMerger merger(raw);
  const auto lines = detail::split_lines(text);
  int facet_line = 0;  // line of the open "facet", 0 outside a facet
  bool in_loop = false;
  std::size_t facet_first_corner = 0;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const int line_number = static_cast<int>(i) + 1;
    const auto tokens = detail::split_whitespace(lines[i]);
    if (tokens.empty()) continue;
    const std::string keyword = detail::to_lower(std::string(tokens[0]));
    if (keyword == "solid" || keyword == "endsolid") {
      if (facet_line != 0)
        fail_line(path, line_number,
                  quote_token(tokens[0]) + " inside the facet started at line " +
                      std::to_string(facet_line));
    } else if (keyword == "facet") {
      if (facet_line != 0)
        fail_line(path, line_number,
                  "'facet' before the 'endfacet' of the facet started at line " +
                      std::to_string(facet_line));
      facet_line = line_number;
      facet_first_corner = raw.corners.size();
    } else if (keyword == "outer") {
      if (facet_line == 0 || in_loop) fail_line(path, line_number, "unexpected 'outer loop'");
      in_loop = true;
    } else if (keyword == "vertex") {
      if (!in_loop) fail_line(path, line_number, "'vertex' outside an 'outer loop'");
      if (tokens.size() != 4)
        fail_line(path, line_number,
                  "vertex: expected 3 numbers, found " + std::to_string(tokens.size() - 1));
      double x[3];
      for (int a = 0; a < 3; ++a) {
        if (!parse_double(tokens[static_cast<std::size_t>(a) + 1], x[a]))
          fail_line(path, line_number,
                    "vertex: expected a number, got " +
                        quote_token(tokens[static_cast<std::size_t>(a) + 1]));
      }
      if (!std::isfinite(x[0]) || !std::isfinite(x[1]) || !std::isfinite(x[2]))
        fail_line(path, line_number,
                  "vertex has a non-finite coordinate (" + number(x[0]) + " " + number(x[1]) + " " +
                      number(x[2]) + ")");
      raw.corners.push_back(merger.index(x[0], x[1], x[2]));
    } else if (keyword == "endloop") {
      if (!in_loop) fail_line(path, line_number, "'endloop' without 'outer loop'");
      in_loop = false;
    } else if (keyword == "endfacet") {
      if (facet_line == 0 || in_loop)
        fail_line(path, line_number,
                  in_loop ? "'endfacet' before 'endloop'" : "unexpected 'endfacet'");
      const std::size_t n = raw.corners.size() - facet_first_corner;
      if (n < 3)
        fail_line(path, facet_line,
                  "facet has " + std::to_string(n) + " vertices, at least 3 needed");
      raw.end_face(facet_line);
      facet_line = 0;
    } else {
      fail_line(path, line_number,
                "unexpected " + quote_token(tokens[0]) + " in an ASCII STL file");
    }
  }
  if (facet_line != 0)
    fail_line(path, std::max<int>(1, static_cast<int>(lines.size())),
              "file ends inside the facet started at line " + std::to_string(facet_line) +
                  " (truncated file?)");
  return raw;
}

RawSurface read_stl(const std::string& path, std::string_view bytes) {
  const std::string_view start = detail::trim(bytes.substr(0, 512));
  const bool says_solid = start.substr(0, 5) == "solid";
  if (bytes.size() >= 84) {
    const std::uint64_t n = load_u32_le(reinterpret_cast<const unsigned char*>(bytes.data()) + 80);
    const std::uint64_t expected = 84 + 50 * n;
    if (expected == bytes.size()) return read_stl_binary(path, bytes);
    // A NUL byte means binary even when the 80-byte header starts with "solid".
    if (!says_solid || bytes.find('\0') != std::string_view::npos)
      fail(path + ": byte 80: binary STL header says " + std::to_string(n) +
           " facets (84 + 50*n = " + std::to_string(expected) + " bytes), but the file has " +
           std::to_string(bytes.size()) + " bytes" +
           (bytes.size() < expected ? " (truncated file?)" : ""));
  } else if (!says_solid) {
    fail(path + ": " + std::to_string(bytes.size()) +
         " bytes: too short for a binary STL (84-byte header) and does not start with 'solid'");
  }
  return read_stl_ascii(path, bytes);
}

// ---------------------------------------------------------------------------------------------
// PLY

enum class PlyType { int8, uint8, int16, uint16, int32, uint32, float32, float64 };

std::optional<PlyType> ply_type(const std::string& name) {
  static const std::pair<const char*, PlyType> table[] = {
      {"char", PlyType::int8},      {"int8", PlyType::int8},       {"uchar", PlyType::uint8},
      {"uint8", PlyType::uint8},    {"short", PlyType::int16},     {"int16", PlyType::int16},
      {"ushort", PlyType::uint16},  {"uint16", PlyType::uint16},   {"int", PlyType::int32},
      {"int32", PlyType::int32},    {"uint", PlyType::uint32},     {"uint32", PlyType::uint32},
      {"float", PlyType::float32},  {"float32", PlyType::float32}, {"double", PlyType::float64},
      {"float64", PlyType::float64}};
  for (const auto& [n, t] : table) {
    if (name == n) return t;
  }
  return std::nullopt;
}

std::size_t ply_size(PlyType t) {
  switch (t) {
    case PlyType::int8:
    case PlyType::uint8:
      return 1;
    case PlyType::int16:
    case PlyType::uint16:
      return 2;
    case PlyType::int32:
    case PlyType::uint32:
    case PlyType::float32:
      return 4;
    case PlyType::float64:
      return 8;
  }
  return 0;
}

bool ply_is_float(PlyType t) {
  return t == PlyType::float32 || t == PlyType::float64;
}

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::float32;  ///< the item type for lists
  bool is_list = false;
  PlyType count_type = PlyType::uint8;
};

struct PlyElement {
  std::string name;
  long long count = 0;
  int line = 0;
  std::vector<PlyProperty> properties;
};

enum class PlyFormat { ascii, binary_le, binary_be };

/// Reads binary PLY values with bounds checks; offsets in messages are from the file start.
class BinaryReader {
 public:
  BinaryReader(const std::string& file, std::string_view bytes, std::size_t offset, bool big_endian)
      : file_(file), bytes_(bytes), pos_(offset), big_endian_(big_endian) {}
  std::size_t pos() const { return pos_; }

  /// Reads one value; integers are exact in the double.
  double read(PlyType t, const std::string& what) {
    const std::size_t n = ply_size(t);
    if (pos_ + n > bytes_.size())
      fail(file_ + ": byte " + std::to_string(pos_) + ": file ends inside " + what +
           " (truncated file?)");
    unsigned char b[8];
    std::memcpy(b, bytes_.data() + pos_, n);
    pos_ += n;
    const bool host_big = is_host_big_endian();
    if (n > 1 && big_endian_ != host_big) std::reverse(b, b + n);
    switch (t) {
      case PlyType::int8:
        return static_cast<double>(static_cast<std::int8_t>(b[0]));
      case PlyType::uint8:
        return static_cast<double>(b[0]);
      case PlyType::int16:
        return load<std::int16_t>(b);
      case PlyType::uint16:
        return load<std::uint16_t>(b);
      case PlyType::int32:
        return load<std::int32_t>(b);
      case PlyType::uint32:
        return load<std::uint32_t>(b);
      case PlyType::float32:
        return load<float>(b);
      case PlyType::float64:
        return load<double>(b);
    }
    return 0;
  }

 private:
  template <class T>
  static double load(const unsigned char* b) {
    T v;
    std::memcpy(&v, b, sizeof v);
    return static_cast<double>(v);
  }
  static bool is_host_big_endian() {
    const std::uint16_t one = 1;
    unsigned char first = 0;
    std::memcpy(&first, &one, 1);
    return first == 0;
  }
  const std::string& file_;
  std::string_view bytes_;
  std::size_t pos_;
  bool big_endian_;
};

// A PLY header: its elements with their properties, the format, and where the body starts.
struct PlyHeader {
  std::vector<PlyElement> elements;
  PlyFormat format = PlyFormat::ascii;
  std::size_t body = 0;  // byte offset of the first byte after "end_header"
  int lines = 0;         // header lines
};

PlyHeader read_ply_header(const std::string& path, std::string_view bytes) {
  // Header: text lines up to "end_header".
  PlyHeader header;
  std::vector<PlyElement>& elements = header.elements;
  PlyFormat& format = header.format;
  bool have_format = false;
  std::size_t pos = 0;
  int line_number = 0;
  bool ended = false;
  while (pos < bytes.size()) {
    std::size_t end = bytes.find('\n', pos);
    if (end == std::string_view::npos) end = bytes.size();
    std::string_view line = bytes.substr(pos, end - pos);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    pos = std::min(end + 1, bytes.size());
    ++line_number;
    const auto tokens = detail::split_whitespace(line);
    if (line_number == 1) {
      if (tokens.size() != 1 || tokens[0] != "ply")
        fail_line(path, 1, "expected the magic line 'ply'");
      continue;
    }
    if (tokens.empty()) continue;
    const std::string keyword(tokens[0]);
    if (keyword == "comment" || keyword == "obj_info") continue;
    if (keyword == "end_header") {
      ended = true;
      break;
    }
    if (keyword == "format") {
      if (tokens.size() != 3)
        fail_line(path, line_number,
                  "expected 'format <ascii|binary_little_endian|"
                  "binary_big_endian> 1.0'");
      if (tokens[1] == "ascii")
        format = PlyFormat::ascii;
      else if (tokens[1] == "binary_little_endian")
        format = PlyFormat::binary_le;
      else if (tokens[1] == "binary_big_endian")
        format = PlyFormat::binary_be;
      else
        fail_line(path, line_number, "unknown PLY format " + quote_token(tokens[1]));
      have_format = true;
    } else if (keyword == "element") {
      long long n = 0;
      if (tokens.size() != 3 || !parse_integer(tokens[2], n) || n < 0)
        fail_line(path, line_number, "expected 'element <name> <count>'");
      elements.push_back({std::string(tokens[1]), n, line_number, {}});
    } else if (keyword == "property") {
      if (elements.empty()) fail_line(path, line_number, "'property' before any 'element'");
      PlyProperty p;
      const auto type_of = [&](std::string_view name) {
        const auto t = ply_type(std::string(name));
        if (!t) fail_line(path, line_number, "unsupported PLY property type " + quote_token(name));
        return *t;
      };
      if (tokens.size() >= 2 && tokens[1] == "list") {
        if (tokens.size() != 5)
          fail_line(path, line_number, "expected 'property list <count type> <item type> <name>'");
        p.is_list = true;
        p.count_type = type_of(tokens[2]);
        p.type = type_of(tokens[3]);
        p.name = std::string(tokens[4]);
        if (ply_is_float(p.count_type))
          fail_line(path, line_number,
                    "unsupported PLY list count type " + quote_token(tokens[2]) +
                        " (must be an integer)");
      } else {
        if (tokens.size() != 3) fail_line(path, line_number, "expected 'property <type> <name>'");
        p.type = type_of(tokens[1]);
        p.name = std::string(tokens[2]);
      }
      elements.back().properties.push_back(std::move(p));
    } else {
      fail_line(path, line_number, "unexpected " + quote_token(tokens[0]) + " in the PLY header");
    }
  }
  if (!ended) fail_line(path, std::max(line_number, 1), "file ends before 'end_header'");
  if (!have_format) fail_line(path, line_number, "no 'format' line in the header");

  header.body = pos;
  header.lines = line_number;
  return header;
}

// Where a PLY file's x, y, z and corner lists are.
struct PlyLayout {
  const PlyElement* vertex_element = nullptr;
  const PlyElement* face_element = nullptr;
  std::array<int, 3> xyz_property{-1, -1, -1};
  int list_property = -1;
};

PlyLayout ply_layout(const std::string& path, const PlyHeader& header) {
  PlyLayout layout;
  const PlyElement*& vertex_element = layout.vertex_element;
  const PlyElement*& face_element = layout.face_element;
  std::array<int, 3>& xyz_property = layout.xyz_property;
  int& list_property = layout.list_property;
  const std::vector<PlyElement>& elements = header.elements;
  const int line_number = header.lines;
  for (const auto& e : elements) {
    if (e.name == "vertex") {
      vertex_element = &e;
      for (std::size_t i = 0; i < e.properties.size(); ++i) {
        const auto& p = e.properties[i];
        for (int a = 0; a < 3; ++a) {
          if (p.name == std::string(1, static_cast<char>('x' + a))) {
            if (p.is_list) fail_line(path, e.line, "vertex property '" + p.name + "' is a list");
            xyz_property[static_cast<std::size_t>(a)] = static_cast<int>(i);
          }
        }
      }
      for (int a = 0; a < 3; ++a) {
        if (xyz_property[static_cast<std::size_t>(a)] < 0)
          fail_line(path, e.line,
                    "element vertex has no property '" +
                        std::string(1, static_cast<char>('x' + a)) + "'");
      }
    } else if (e.name == "face") {
      face_element = &e;
      for (std::size_t i = 0; i < e.properties.size(); ++i) {
        const auto& p = e.properties[i];
        if (p.name == "vertex_indices" || p.name == "vertex_index") {
          if (!p.is_list || ply_is_float(p.type))
            fail_line(path, e.line, "face property '" + p.name + "' must be a list of integers");
          list_property = static_cast<int>(i);
        }
      }
      if (list_property < 0)
        fail_line(path, e.line, "element face has no list property 'vertex_indices'");
    }
  }
  if (vertex_element == nullptr) fail_line(path, line_number, "no 'element vertex' in the header");
  if (face_element == nullptr)
    fail_line(path, line_number,
              "no 'element face' in the header (triangle strips and point "
              "clouds are not supported)");

  return layout;
}

void check_ply_face_count(long long n, const std::string& at) {
  if (n < 3) fail(at + "has " + std::to_string(n) + " corners, at least 3 needed");
}

// Property k of element e, value v: a vertex coordinate when it is x, y or z of the vertices.
void set_coordinate(const PlyLayout& layout, const PlyElement& e, std::size_t k, double v,
                    std::array<double, 3>& x) {
  if (&e != layout.vertex_element) return;
  for (int a = 0; a < 3; ++a) {
    if (layout.xyz_property[static_cast<std::size_t>(a)] == static_cast<int>(k))
      x[static_cast<std::size_t>(a)] = v;
  }
}

void read_ply_ascii_body(const std::string& path, std::string_view bytes, const PlyHeader& header,
                         const PlyLayout& layout, RawSurface& raw) {
  const std::size_t pos = header.body;
  const int line_number = header.lines;
  std::array<double, 3> x{};
  TokenStream src(path, bytes.substr(pos), line_number + 1, false);
  for (const auto& e : header.elements) {
    for (long long i = 0; i < e.count; ++i) {
      const std::string what =
          "element " + e.name + " " + std::to_string(i) + " of " + std::to_string(e.count);
      const int line = src.at_end() ? src.last_line() : src.peek().line;
      const auto at = [&] { return path + ":" + std::to_string(line) + ": " + e.name + " "; };
      for (std::size_t k = 0; k < e.properties.size(); ++k) {
        const auto& p = e.properties[k];
        if (!p.is_list) {
          const double v = ply_is_float(p.type)
                               ? src.real(p.name + " of " + what)
                               : static_cast<double>(src.integer(p.name + " of " + what));
          set_coordinate(layout, e, k, v, x);
          continue;
        }
        const long long n = src.integer("the list count of " + p.name + " of " + what);
        if (n < 0) fail_line(path, line, "negative list count " + std::to_string(n));
        const bool corners =
            &e == layout.face_element && static_cast<int>(k) == layout.list_property;
        if (corners) check_ply_face_count(n, at());
        for (long long c = 0; c < n; ++c) {
          if (ply_is_float(p.type)) {
            src.real(p.name + " of " + what);
          } else {
            const long long v = src.integer(p.name + " of " + what);
            if (corners) raw.corners.push_back(v);
          }
        }
      }
      if (&e == layout.vertex_element) add_vertex(raw, x[0], x[1], x[2], at);
      if (&e == layout.face_element) raw.end_face(line);
    }
  }
  if (!src.at_end())
    fail_line(path, src.peek().line,
              "unexpected " + quote_token(src.peek().text) + " after the last element");
}

void read_ply_binary_body(const std::string& path, std::string_view bytes, const PlyHeader& header,
                          const PlyLayout& layout, RawSurface& raw) {
  const std::size_t pos = header.body;
  const PlyFormat format = header.format;
  std::array<double, 3> x{};
  BinaryReader src(path, bytes, pos, format == PlyFormat::binary_be);
  for (const auto& e : header.elements) {
    for (long long i = 0; i < e.count; ++i) {
      const std::size_t start = src.pos();
      const std::string what = e.name + " " + std::to_string(i);
      const auto at = [&] { return path + ": byte " + std::to_string(start) + ": " + what + " "; };
      for (std::size_t k = 0; k < e.properties.size(); ++k) {
        const auto& p = e.properties[k];
        if (!p.is_list) {
          const double v = src.read(p.type, what);
          set_coordinate(layout, e, k, v, x);
          continue;
        }
        const double count = src.read(p.count_type, what);
        if (count < 0) fail(at() + "has a negative list count " + number(count));
        const auto n = static_cast<long long>(count);
        const bool corners =
            &e == layout.face_element && static_cast<int>(k) == layout.list_property;
        if (corners) check_ply_face_count(n, at());
        for (long long c = 0; c < n; ++c) {
          const double v = src.read(p.type, what);
          if (corners) raw.corners.push_back(static_cast<long long>(v));
        }
      }
      if (&e == layout.vertex_element) add_vertex(raw, x[0], x[1], x[2], at);
      if (&e == layout.face_element) raw.end_face(static_cast<long long>(start));
    }
  }
  if (src.pos() != bytes.size())
    fail(path + ": byte " + std::to_string(src.pos()) + ": " +
         std::to_string(bytes.size() - src.pos()) + " unexpected bytes after the last element");
}

RawSurface read_ply(const std::string& path, std::string_view bytes) {
  const PlyHeader header = read_ply_header(path, bytes);
  const PlyLayout layout = ply_layout(path, header);
  RawSurface raw;
  raw.file = path;
  raw.binary = header.format != PlyFormat::ascii;
  reserve(raw, layout.vertex_element->count, layout.face_element->count);
  if (header.format == PlyFormat::ascii) {
    read_ply_ascii_body(path, bytes, header, layout, raw);
  } else {
    read_ply_binary_body(path, bytes, header, layout, raw);
  }
  return raw;
}

// ---------------------------------------------------------------------------------------------
// Validation and triangulation

SurfaceMeshReadResult finish(const RawSurface& raw, const SurfaceMeshReadOptions& options) {
  SurfaceMeshReadResult result;
  const auto nv = static_cast<long long>(raw.vertex_count());
  if (nv == 0) fail(raw.file + ": empty mesh (no vertices)");
  if (raw.face_count() == 0) fail(raw.file + ": empty mesh (no faces)");
  std::vector<int> triangles;
  triangles.reserve(3 * raw.face_count());
  for (std::size_t f = 0; f < raw.face_count(); ++f) {
    const std::size_t begin = raw.face_start[f], end = raw.face_start[f + 1];
    const std::size_t n = end - begin;
    if (n < 3) fail(raw.at_face(f) + "has " + std::to_string(n) + " corners, at least 3 needed");
    for (std::size_t c = begin; c < end; ++c) {
      const long long v = raw.corners[c];
      if (v < 0 || v >= nv)
        fail(raw.at_face(f) + "references vertex " + std::to_string(v + raw.index_base) +
             ", but there are " + std::to_string(nv) + " vertices" +
             (raw.index_base == 0 ? " (numbered from 0)" : ""));
    }
    bool repeated = false;
    long long repeated_index = 0;
    for (std::size_t a = begin; a < end && !repeated; ++a) {
      for (std::size_t b = a + 1; b < end && !repeated; ++b) {
        if (raw.corners[a] == raw.corners[b]) {
          repeated = true;
          repeated_index = raw.corners[a];
        }
      }
    }
    if (repeated) {
      if (options.drop_degenerate_faces) {
        ++result.dropped_faces;
        continue;
      }
      fail(raw.at_face(f) + "is degenerate: it repeats vertex " +
           std::to_string(repeated_index + raw.index_base));
    }
    if (n > 3) ++result.polygons_triangulated;
    for (std::size_t c = begin + 1; c + 1 < end; ++c) {
      triangles.push_back(static_cast<int>(raw.corners[begin]));
      triangles.push_back(static_cast<int>(raw.corners[c]));
      triangles.push_back(static_cast<int>(raw.corners[c + 1]));
    }
  }
  if (triangles.empty())
    fail(raw.file + ": empty mesh (all " + std::to_string(raw.face_count()) +
         " faces were degenerate and dropped)");
  SurfaceMesh mesh;
  mesh.vertices = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>(
      raw.xyz.data(), nv, 3);
  mesh.triangles = Eigen::Map<const Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>>(
      triangles.data(), static_cast<Eigen::Index>(triangles.size() / 3), 3);
  result.merged_stl_corners = raw.merged_stl_corners;
  result.mesh = std::move(mesh);
  return result;
}

bool fail_write(std::string* error, const std::string& message) {
  if (error != nullptr) *error = message;
  return false;
}

/// Writers must not produce unreadable files.
bool check_for_write(const std::string& path, const SurfaceMesh& mesh, std::string* error) {
  if (mesh.vertices.cols() != 3 || mesh.triangles.cols() != 3)
    return fail_write(error, path + ": cannot write: vertices and triangles must have 3 columns");
  if (mesh.triangles.size() > 0 &&
      (mesh.triangles.minCoeff() < 0 || mesh.triangles.maxCoeff() >= mesh.vertices.rows()))
    return fail_write(error, path + ": cannot write: a triangle references a vertex outside 0.." +
                                 std::to_string(mesh.vertices.rows() - 1));
  if (!mesh.vertices.allFinite())
    return fail_write(error, path + ": cannot write: a vertex has a non-finite coordinate");
  return true;
}

void append_vertices(std::string& out, const SurfaceMesh& mesh, const char* prefix) {
  for (Eigen::Index i = 0; i < mesh.vertices.rows(); ++i) {
    out += prefix;
    for (int a = 0; a < 3; ++a) {
      if (a > 0) out += ' ';
      detail::append_double(out, mesh.vertices(i, a));
    }
    out += '\n';
  }
}

// "3 a b c" lines, 0-based: the face lists of OFF and ASCII PLY.
void append_counted_triangles(std::string& out, const SurfaceMesh& mesh) {
  for (Eigen::Index t = 0; t < mesh.triangles.rows(); ++t)
    out += "3 " + std::to_string(mesh.triangles(t, 0)) + " " +
           std::to_string(mesh.triangles(t, 1)) + " " + std::to_string(mesh.triangles(t, 2)) + "\n";
}

}  // namespace

SurfaceMeshReadResult read_surface_mesh(const std::string& path,
                                        const SurfaceMeshReadOptions& options) {
  return detail::guarded_read<SurfaceMeshReadResult>(path, [&] {
    const std::string ext = detail::to_lower(std::filesystem::path(path).extension().string());
    if (ext != ".obj" && ext != ".off" && ext != ".stl" && ext != ".ply") {
      SurfaceMeshReadResult failed;
      failed.error = path + ": unknown surface-mesh extension " +
                     quote_token(ext.empty() ? std::string("(none)") : ext) +
                     " (expected .obj, .off, .stl or .ply)";
      return failed;
    }
    const std::string bytes = detail::read_whole_file(path);
    RawSurface raw;
    if (ext == ".obj")
      raw = read_obj(path, bytes);
    else if (ext == ".off")
      raw = read_off(path, bytes);
    else if (ext == ".stl")
      raw = read_stl(path, bytes);
    else
      raw = read_ply(path, bytes);
    return finish(raw, options);
  });
}

std::string SurfaceCheck::report() const {
  std::ostringstream s;
  s.precision(6);
  if (closed_manifold())
    s << "closed manifold";
  else if (triangles == 0)
    s << "empty";
  else if (!closed())
    s << "not closed";
  else
    s << "closed but not a consistently oriented manifold";
  s << ": " << vertices << " vertices, " << triangles << " triangles, " << edges << " edges";
  if (!closed_manifold())
    s << ", " << boundary_edges << " boundary edges, " << non_manifold_edges
      << " non-manifold edges, " << inconsistent_edges << " inconsistently oriented edges, "
      << degenerate_triangles << " degenerate triangles";
  if (unreferenced_vertices > 0) s << ", " << unreferenced_vertices << " unreferenced vertices";
  s << ", signed volume " << signed_volume;
  return s.str();
}

SurfaceCheck check_surface(const SurfaceMesh& mesh) {
  SurfaceCheck check;
  check.vertices = static_cast<int>(mesh.vertices.rows());
  check.triangles = static_cast<int>(mesh.triangles.rows());
  if (check.triangles == 0) {
    check.unreferenced_vertices = check.vertices;
    return check;
  }
  // Half-edges sorted by their undirected edge; direction +1 when stored as (low, high).
  struct HalfEdge {
    std::int64_t key;
    int direction;
  };
  std::vector<HalfEdge> half_edges;
  half_edges.reserve(3 * static_cast<std::size_t>(check.triangles));
  std::vector<char> used(static_cast<std::size_t>(check.vertices), 0);
  const Eigen::Vector3d centre =
      0.5 * (mesh.vertices.colwise().minCoeff() + mesh.vertices.colwise().maxCoeff()).transpose();
  double six_volume = 0.0;
  for (Eigen::Index t = 0; t < mesh.triangles.rows(); ++t) {
    const int v[3] = {mesh.triangles(t, 0), mesh.triangles(t, 1), mesh.triangles(t, 2)};
    for (const int i : v) used[static_cast<std::size_t>(i)] = 1;
    if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2]) {
      ++check.degenerate_triangles;
      continue;
    }
    for (int a = 0; a < 3; ++a) {
      const int p = v[a], q = v[(a + 1) % 3];
      const std::int64_t lo = std::min(p, q), hi = std::max(p, q);
      half_edges.push_back({(lo << 32) | hi, p < q ? 1 : -1});
    }
    const Eigen::Vector3d a = mesh.vertices.row(v[0]).transpose() - centre;
    const Eigen::Vector3d b = mesh.vertices.row(v[1]).transpose() - centre;
    const Eigen::Vector3d c = mesh.vertices.row(v[2]).transpose() - centre;
    six_volume += a.dot(b.cross(c));
  }
  check.signed_volume = six_volume / 6.0;
  for (const char u : used) check.unreferenced_vertices += u == 0 ? 1 : 0;
  std::sort(half_edges.begin(), half_edges.end(),
            [](const HalfEdge& a, const HalfEdge& b) { return a.key < b.key; });
  for (std::size_t i = 0; i < half_edges.size();) {
    std::size_t j = i;
    int direction_sum = 0;
    while (j < half_edges.size() && half_edges[j].key == half_edges[i].key)
      direction_sum += half_edges[j++].direction;
    ++check.edges;
    const std::size_t uses = j - i;
    if (uses == 1)
      ++check.boundary_edges;
    else if (uses > 2)
      ++check.non_manifold_edges;
    else if (direction_sum != 0)
      ++check.inconsistent_edges;
    i = j;
  }
  return check;
}

bool write_obj(const std::string& path, const SurfaceMesh& mesh, std::string* error) {
  try {
    if (!check_for_write(path, mesh, error)) return false;
    std::string out = "# sinew surface: " + std::to_string(mesh.vertices.rows()) + " vertices, " +
                      std::to_string(mesh.triangles.rows()) + " triangles\n";
    out.reserve(static_cast<std::size_t>(mesh.vertices.rows()) * 60 +
                static_cast<std::size_t>(mesh.triangles.rows()) * 24);
    append_vertices(out, mesh, "v ");
    for (Eigen::Index t = 0; t < mesh.triangles.rows(); ++t)
      out += "f " + std::to_string(mesh.triangles(t, 0) + 1) + " " +
             std::to_string(mesh.triangles(t, 1) + 1) + " " +
             std::to_string(mesh.triangles(t, 2) + 1) + "\n";
    return detail::write_file_atomically(path, out, error);
  } catch (const std::exception& e) {
    return fail_write(error, path + ": " + e.what());
  }
}

bool write_off(const std::string& path, const SurfaceMesh& mesh, std::string* error) {
  try {
    if (!check_for_write(path, mesh, error)) return false;
    std::string out = "OFF\n" + std::to_string(mesh.vertices.rows()) + " " +
                      std::to_string(mesh.triangles.rows()) + " 0\n";
    out.reserve(static_cast<std::size_t>(mesh.vertices.rows()) * 60 +
                static_cast<std::size_t>(mesh.triangles.rows()) * 24);
    append_vertices(out, mesh, "");
    append_counted_triangles(out, mesh);
    return detail::write_file_atomically(path, out, error);
  } catch (const std::exception& e) {
    return fail_write(error, path + ": " + e.what());
  }
}

bool write_stl(const std::string& path, const SurfaceMesh& mesh, std::string* error) {
  try {
    if (!check_for_write(path, mesh, error)) return false;
    std::string out(80, ' ');
    out.replace(0, 28, "sinew surface (binary STL)  ");
    const auto count = static_cast<std::uint32_t>(mesh.triangles.rows());
    out.append(reinterpret_cast<const char*>(&count), 4);
    auto put = [&](const Eigen::Vector3d& v) {
      for (int i = 0; i < 3; ++i) {
        const auto f = static_cast<float>(v[i]);
        out.append(reinterpret_cast<const char*>(&f), 4);
      }
    };
    for (Eigen::Index t = 0; t < mesh.triangles.rows(); ++t) {
      const Eigen::Vector3d a = mesh.vertices.row(mesh.triangles(t, 0)).transpose();
      const Eigen::Vector3d b = mesh.vertices.row(mesh.triangles(t, 1)).transpose();
      const Eigen::Vector3d c = mesh.vertices.row(mesh.triangles(t, 2)).transpose();
      const Eigen::Vector3d n = (b - a).cross(c - a);
      put(n.norm() > 0.0 ? Eigen::Vector3d(n.normalized()) : Eigen::Vector3d::Zero());
      put(a);
      put(b);
      put(c);
      out.append(2, '\0');
    }
    return detail::write_file_atomically(path, out, error);
  } catch (const std::exception& e) {
    return fail_write(error, path + ": " + e.what());
  }
}

bool write_ply(const std::string& path, const SurfaceMesh& mesh, std::string* error) {
  try {
    if (!check_for_write(path, mesh, error)) return false;
    std::string out = "ply\nformat ascii 1.0\ncomment sinew surface\nelement vertex " +
                      std::to_string(mesh.vertices.rows()) +
                      "\nproperty double x\nproperty double y\nproperty double z\nelement face " +
                      std::to_string(mesh.triangles.rows()) +
                      "\nproperty list uchar int vertex_indices\nend_header\n";
    append_vertices(out, mesh, "");
    append_counted_triangles(out, mesh);
    return detail::write_file_atomically(path, out, error);
  } catch (const std::exception& e) {
    return fail_write(error, path + ": " + e.what());
  }
}

bool write_surface_mesh(const std::string& path, const SurfaceMesh& mesh, std::string* error) {
  std::string extension = std::filesystem::path(path).extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (extension == ".obj") return write_obj(path, mesh, error);
  if (extension == ".off") return write_off(path, mesh, error);
  if (extension == ".stl") return write_stl(path, mesh, error);
  if (extension == ".ply") return write_ply(path, mesh, error);
  return fail_write(error, path + ": unknown surface format '" + extension +
                               "' (expected .obj, .off, .stl or .ply)");
}

}  // namespace sinew::offline::io
