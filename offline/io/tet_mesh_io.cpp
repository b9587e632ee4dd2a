#include "offline/io/tet_mesh_io.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <limits>
#include <locale>
#include <new>
#include <optional>
#include <sstream>

#include "offline/io/io_common.hpp"

namespace sinew::offline {
namespace {

/// Internal failure carrying the final one-line message; never leaves this file.
struct ReadError {
  std::string message;
};

std::string format_error(const std::string& file, int line, const std::string& what) {
  return file + ":" + std::to_string(line) + ": " + what;
}

std::string to_lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::string to_upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

/// Shortens a token for quoting in a message.
std::string quoted(const std::string& token) {
  std::string s = token.size() > 40 ? token.substr(0, 40) + "..." : token;
  for (char& c : s) {
    if (!std::isprint(static_cast<unsigned char>(c))) c = '?';
  }
  return "'" + s + "'";
}

bool parse_double(const std::string& token, double& value) {
  if (token.empty()) return false;
  errno = 0;
  char* end = nullptr;
  value = std::strtod(token.c_str(), &end);
  return end == token.c_str() + token.size();  // overflow gives ±inf, caught as non-finite later
}

bool parse_integer(const std::string& token, long long& value) {
  if (token.empty()) return false;
  errno = 0;
  char* end = nullptr;
  value = std::strtoll(token.c_str(), &end, 10);
  return end == token.c_str() + token.size() && errno != ERANGE;
}

struct Line {
  int number = 0;  ///< 1-based line number in the file
  std::vector<std::string> tokens;
};

/// The non-blank lines of a text file, '#' comments stripped, split into whitespace tokens.
class LineSource {
 public:
  LineSource(const std::string& path, bool commas_are_spaces) : path_(path) {
    std::error_code ec;
    if (std::filesystem::is_directory(path, ec))
      throw ReadError{path + ": cannot read: is a directory"};
    std::ifstream in(path, std::ios::binary);
    if (!in) {
      const int e = errno;
      throw ReadError{path + ": cannot open file" +
                      (e != 0 ? std::string(" (") + std::strerror(e) + ")" : "")};
    }
    std::string text;
    int number = 0;
    while (std::getline(in, text)) {
      ++number;
      if (const auto hash = text.find('#'); hash != std::string::npos) text.erase(hash);
      if (commas_are_spaces) std::replace(text.begin(), text.end(), ',', ' ');
      Line line;
      line.number = number;
      std::istringstream words(text);
      for (std::string w; words >> w;) line.tokens.push_back(w);
      if (!line.tokens.empty()) lines_.push_back(std::move(line));
    }
    if (in.bad()) throw ReadError{path + ": read error after line " + std::to_string(number)};
    total_lines_ = number;
  }

  bool at_end() const { return next_ >= lines_.size(); }
  const Line& peek() const { return lines_[next_]; }
  const Line& take() { return lines_[next_++]; }
  int total_lines() const { return std::max(total_lines_, 1); }
  const std::string& path() const { return path_; }

  [[noreturn]] void fail(int line, const std::string& what) const {
    throw ReadError{format_error(path_, line, what)};
  }
  [[noreturn]] void fail_at_end(const std::string& what) const { fail(total_lines(), what); }

  long long integer(const Line& line, std::size_t i, const char* what) const {
    long long v = 0;
    if (!parse_integer(line.tokens[i], v))
      fail(line.number,
           std::string("expected an integer ") + what + ", got " + quoted(line.tokens[i]));
    return v;
  }
  double real(const Line& line, std::size_t i, const char* what) const {
    double v = 0;
    if (!parse_double(line.tokens[i], v))
      fail(line.number,
           std::string("expected a number ") + what + ", got " + quoted(line.tokens[i]));
    return v;
  }
  /// A declared entry count: a non-negative integer that fits an int.
  int count(const Line& line, std::size_t i, const char* what) const {
    const long long n = integer(line, i, what);
    if (n < 0 || n > INT_MAX)
      fail(line.number, std::string("invalid ") + what + " " + std::to_string(n));
    return static_cast<int>(n);
  }

 private:
  std::string path_;
  std::vector<Line> lines_;
  std::size_t next_ = 0;
  int total_lines_ = 0;
};

/// What the format parsers produce: entries as written in the file, with their line numbers.
struct RawMesh {
  std::string vertex_file, tet_file;
  int base = 1;  ///< index of the first vertex in the file's numbering
  std::vector<std::array<double, 3>> vertices;
  std::vector<int> vertex_lines;
  std::vector<std::array<long long, 4>> tets;  ///< vertex indices as written (file numbering)
  std::vector<long long> tet_labels;           ///< element number used in messages
  std::vector<int> tet_lines;
};

constexpr std::size_t kReserveCap = 1 << 20;  // never trust a header with a huge allocation

void reserve_for(RawMesh& raw, int vertices, int tets) {
  if (vertices >= 0) {
    raw.vertices.reserve(std::min<std::size_t>(vertices, kReserveCap));
    raw.vertex_lines.reserve(std::min<std::size_t>(vertices, kReserveCap));
  }
  if (tets >= 0) {
    raw.tets.reserve(std::min<std::size_t>(tets, kReserveCap));
    raw.tet_labels.reserve(std::min<std::size_t>(tets, kReserveCap));
    raw.tet_lines.reserve(std::min<std::size_t>(tets, kReserveCap));
  }
}

// ---------------------------------------------------------------------------------------------
// Medit .mesh

bool is_medit_keyword(const Line& line) {
  double unused = 0;
  return std::isalpha(static_cast<unsigned char>(line.tokens[0][0])) &&
         !parse_double(line.tokens[0], unused);
}

/// The count after a keyword: on the keyword's line or alone on the next line.
int medit_count(LineSource& src, const Line& keyword_line, const std::string& keyword) {
  if (keyword_line.tokens.size() >= 2) {
    if (keyword_line.tokens.size() > 2)
      src.fail(keyword_line.number,
               "unexpected " + quoted(keyword_line.tokens[2]) + " after " + keyword + " count");
    return src.count(keyword_line, 1, ("(" + keyword + " count)").c_str());
  }
  if (src.at_end()) src.fail_at_end("file ends before the " + keyword + " count");
  const Line& line = src.take();
  if (line.tokens.size() != 1)
    src.fail(line.number, "expected the " + keyword + " count alone on the line, got " +
                              std::to_string(line.tokens.size()) + " values");
  return src.count(line, 0, ("(" + keyword + " count)").c_str());
}

/// Checks that the i-th of n entries of a section is present; returns its line.
const Line& medit_entry(LineSource& src, const std::string& section, int i, int n) {
  if (src.at_end())
    src.fail_at_end("file ends after " + std::to_string(i) + " of the " + std::to_string(n) + " " +
                    section + " entries (truncated file?)");
  if (is_medit_keyword(src.peek()))
    src.fail(src.peek().number, "section " + quoted(src.peek().tokens[0]) + " starts after only " +
                                    std::to_string(i) + " of the " + std::to_string(n) + " " +
                                    section + " entries");
  return src.take();
}

RawMesh read_medit(const std::string& path) {
  LineSource src(path, false);
  RawMesh raw;
  raw.vertex_file = raw.tet_file = path;
  raw.base = 1;
  int vertices_line = 0, tets_line = 0;
  while (!src.at_end()) {
    const Line& line = src.take();
    if (!is_medit_keyword(line))
      src.fail(line.number, "unexpected " + quoted(line.tokens[0]) + " outside a section");
    const std::string keyword = line.tokens[0];
    const std::string lower = to_lower(keyword);
    if (lower == "end") break;
    if (lower == "meshversionformatted") {
      medit_count(src, line, keyword);
    } else if (lower == "dimension") {
      const int dim = medit_count(src, line, keyword);
      if (dim != 3)
        src.fail(line.number, "Dimension " + std::to_string(dim) + ", only 3 is supported");
    } else if (lower == "vertices") {
      if (vertices_line != 0)
        src.fail(line.number, "second Vertices section (the first is at line " +
                                  std::to_string(vertices_line) + ")");
      vertices_line = line.number;
      const int n = medit_count(src, line, keyword);
      reserve_for(raw, n, -1);
      for (int i = 0; i < n; ++i) {
        const Line& e = medit_entry(src, "Vertices", i, n);
        if (e.tokens.size() != 4 && e.tokens.size() != 3)
          src.fail(e.number, "vertex " + std::to_string(i + 1) + ": expected 'x y z ref', got " +
                                 std::to_string(e.tokens.size()) + " values");
        raw.vertices.push_back(
            {src.real(e, 0, "(x)"), src.real(e, 1, "(y)"), src.real(e, 2, "(z)")});
        if (e.tokens.size() == 4) src.integer(e, 3, "(vertex reference label)");
        raw.vertex_lines.push_back(e.number);
      }
    } else if (lower == "tetrahedra") {
      if (tets_line != 0)
        src.fail(line.number, "second Tetrahedra section (the first is at line " +
                                  std::to_string(tets_line) + ")");
      tets_line = line.number;
      const int n = medit_count(src, line, keyword);
      reserve_for(raw, -1, n);
      for (int i = 0; i < n; ++i) {
        const Line& e = medit_entry(src, "Tetrahedra", i, n);
        if (e.tokens.size() != 5 && e.tokens.size() != 4)
          src.fail(e.number, "tetrahedron " + std::to_string(i + 1) +
                                 ": expected 'v1 v2 v3 v4 ref', got " +
                                 std::to_string(e.tokens.size()) + " values");
        std::array<long long, 4> t{};
        for (std::size_t a = 0; a < 4; ++a) t[a] = src.integer(e, a, "(vertex index)");
        if (e.tokens.size() == 5) src.integer(e, 4, "(tetrahedron reference label)");
        raw.tets.push_back(t);
        raw.tet_labels.push_back(i + 1);
        raw.tet_lines.push_back(e.number);
      }
    } else {
      // Other sections (Triangles, Edges, Corners, Ridges, Normals, ...): skip their data lines.
      while (!src.at_end() && !is_medit_keyword(src.peek())) src.take();
    }
  }
  if (vertices_line == 0) src.fail_at_end("no Vertices section");
  if (tets_line == 0) src.fail_at_end("no Tetrahedra section");
  return raw;
}

// ---------------------------------------------------------------------------------------------
// VegaFEM .veg

bool is_veg_keyword(const Line& line) {
  return line.tokens[0][0] == '*';
}

const Line& veg_entry(LineSource& src, const char* what, int i, int n, int header_line) {
  if (src.at_end())
    src.fail_at_end("file ends after " + std::to_string(i) + " of the " + std::to_string(n) + " " +
                    what + " declared at line " + std::to_string(header_line) +
                    " (truncated file?)");
  if (is_veg_keyword(src.peek()))
    src.fail(src.peek().number, quoted(src.peek().tokens[0]) + " starts after only " +
                                    std::to_string(i) + " of the " + std::to_string(n) + " " +
                                    what + " declared at line " + std::to_string(header_line));
  return src.take();
}

/// After a section's n entries: the next line must start another section (or the file ends).
void veg_expect_section_end(LineSource& src, const char* what, int n, int header_line) {
  if (!src.at_end() && !is_veg_keyword(src.peek()))
    src.fail(src.peek().number, "more " + std::string(what) + " than the " + std::to_string(n) +
                                    " declared at line " + std::to_string(header_line));
}

const Line& veg_header(LineSource& src, const std::string& after) {
  if (src.at_end()) src.fail_at_end("file ends right after " + after);
  if (is_veg_keyword(src.peek()))
    src.fail(src.peek().number,
             "expected the header line after " + after + ", got " + quoted(src.peek().tokens[0]));
  return src.take();
}

RawMesh read_veg(const std::string& path) {
  LineSource src(path, true);
  RawMesh raw;
  raw.vertex_file = raw.tet_file = path;
  raw.base = 1;
  int vertices_line = 0, elements_line = 0;
  while (!src.at_end()) {
    const Line& line = src.take();
    if (!is_veg_keyword(line))
      src.fail(line.number, "unexpected " + quoted(line.tokens[0]) +
                                " outside a section (expected a *KEYWORD such as *VERTICES)");
    const std::string keyword = to_upper(line.tokens[0]);
    if (keyword == "*VERTICES") {
      if (vertices_line != 0)
        src.fail(line.number, "second *VERTICES section (the first is at line " +
                                  std::to_string(vertices_line) + ")");
      vertices_line = line.number;
      const Line& header = veg_header(src, "*VERTICES");
      if (header.tokens.size() < 2)
        src.fail(header.number, "expected the vertex header 'count 3 0 0', got " +
                                    std::to_string(header.tokens.size()) + " value(s)");
      const int n = src.count(header, 0, "(vertex count)");
      const long long dim = src.integer(header, 1, "(dimension)");
      if (dim != 3)
        src.fail(header.number, "vertex dimension " + std::to_string(dim) + ", expected 3");
      reserve_for(raw, n, -1);
      for (int i = 0; i < n; ++i) {
        const Line& e = veg_entry(src, "vertices", i, n, header.number);
        if (e.tokens.size() != 4)
          src.fail(e.number, "expected a vertex line 'index x y z', got " +
                                 std::to_string(e.tokens.size()) + " values");
        const long long index = src.integer(e, 0, "(vertex index)");
        if (index != i + 1)
          src.fail(e.number, "vertex index " + std::to_string(index) + " where " +
                                 std::to_string(i + 1) +
                                 " was expected (vertices are numbered 1, 2, ... in order)");
        raw.vertices.push_back(
            {src.real(e, 1, "(x)"), src.real(e, 2, "(y)"), src.real(e, 3, "(z)")});
        raw.vertex_lines.push_back(e.number);
      }
      veg_expect_section_end(src, "vertex lines", n, header.number);
    } else if (keyword == "*ELEMENTS") {
      if (elements_line != 0)
        src.fail(line.number, "second *ELEMENTS section (the first is at line " +
                                  std::to_string(elements_line) +
                                  "); only one TET section is supported");
      elements_line = line.number;
      const Line& type = veg_header(src, "*ELEMENTS");
      if (to_upper(type.tokens[0]) != "TET" || type.tokens.size() != 1)
        src.fail(type.number, "element type " + quoted(type.tokens[0]) + ", only TET is supported");
      const Line& header = veg_header(src, "TET");
      if (header.tokens.size() < 2)
        src.fail(header.number, "expected the element header 'count 4 0', got " +
                                    std::to_string(header.tokens.size()) + " value(s)");
      const int n = src.count(header, 0, "(element count)");
      const long long npe = src.integer(header, 1, "(vertices per element)");
      if (npe != 4)
        src.fail(header.number, std::to_string(npe) + " vertices per element, expected 4 for TET");
      reserve_for(raw, -1, n);
      for (int i = 0; i < n; ++i) {
        const Line& e = veg_entry(src, "elements", i, n, header.number);
        if (e.tokens.size() != 5)
          src.fail(e.number, "expected an element line 'index v1 v2 v3 v4', got " +
                                 std::to_string(e.tokens.size()) + " values");
        const long long index = src.integer(e, 0, "(element index)");
        if (index != i + 1)
          src.fail(e.number, "element index " + std::to_string(index) + " where " +
                                 std::to_string(i + 1) +
                                 " was expected (elements are numbered 1, 2, ... in order)");
        std::array<long long, 4> t{};
        for (std::size_t a = 0; a < 4; ++a) t[a] = src.integer(e, a + 1, "(vertex index)");
        raw.tets.push_back(t);
        raw.tet_labels.push_back(index);
        raw.tet_lines.push_back(e.number);
      }
      veg_expect_section_end(src, "element lines", n, header.number);
    } else if (keyword == "*INCLUDE") {
      src.fail(line.number, "*INCLUDE is not supported; merge the included file first");
    } else {
      // *MATERIAL, *SET, *REGION, *MASS_DENSITY, ...: skip to the next keyword.
      while (!src.at_end() && !is_veg_keyword(src.peek())) src.take();
    }
  }
  if (vertices_line == 0) src.fail_at_end("no *VERTICES section");
  if (elements_line == 0) src.fail_at_end("no *ELEMENTS section");
  return raw;
}

// ---------------------------------------------------------------------------------------------
// TetGen .node / .ele

void tetgen_expect_end(LineSource& src, const char* what, int n) {
  if (!src.at_end())
    src.fail(src.peek().number, "more " + std::string(what) + " than the " + std::to_string(n) +
                                    " declared in the header at line 1");
}

const Line& tetgen_entry(LineSource& src, const char* what, int i, int n, int header_line) {
  if (src.at_end())
    src.fail_at_end("file ends after " + std::to_string(i) + " of the " + std::to_string(n) + " " +
                    what + " declared at line " + std::to_string(header_line) +
                    " (truncated file?)");
  return src.take();
}

RawMesh read_tetgen(const std::string& path) {
  const std::filesystem::path p(path);
  std::filesystem::path base = p;
  base.replace_extension();
  const std::string node_path = base.string() + ".node", ele_path = base.string() + ".ele";
  RawMesh raw;
  raw.vertex_file = node_path;
  raw.tet_file = ele_path;
  {
    LineSource src(node_path, false);
    if (src.at_end()) src.fail_at_end("empty file, expected the header 'count 3 nattr nbound'");
    const Line& header = src.take();
    if (header.tokens.size() < 2 || header.tokens.size() > 4)
      src.fail(header.number, "expected the header 'count 3 nattr nbound', got " +
                                  std::to_string(header.tokens.size()) + " values");
    const int n = src.count(header, 0, "(vertex count)");
    const long long dim = src.integer(header, 1, "(dimension)");
    if (dim != 3) src.fail(header.number, "dimension " + std::to_string(dim) + ", expected 3");
    const int nattr = header.tokens.size() > 2 ? src.count(header, 2, "(attribute count)") : 0;
    const int nbound =
        header.tokens.size() > 3 ? src.count(header, 3, "(boundary marker count)") : 0;
    if (nbound > 1)
      src.fail(header.number,
               "boundary marker count " + std::to_string(nbound) + ", expected 0 or 1");
    if (n == 0)
      src.fail(header.number, "no vertices (count 0; vertices in a .poly file are not supported)");
    const std::size_t width =
        4 + static_cast<std::size_t>(nattr) + static_cast<std::size_t>(nbound);
    reserve_for(raw, n, -1);
    for (int i = 0; i < n; ++i) {
      const Line& e = tetgen_entry(src, "vertices", i, n, header.number);
      if (e.tokens.size() != width)
        src.fail(e.number, "expected " + std::to_string(width) + " values (index x y z" +
                               (nattr > 0 ? " attributes" : "") + (nbound > 0 ? " marker" : "") +
                               "), got " + std::to_string(e.tokens.size()));
      const long long index = src.integer(e, 0, "(vertex index)");
      if (i == 0) {
        if (index != 0 && index != 1)
          src.fail(e.number, "first vertex index " + std::to_string(index) + ", expected 0 or 1");
        raw.base = static_cast<int>(index);
      } else if (index != raw.base + i) {
        src.fail(e.number, "vertex index " + std::to_string(index) + " where " +
                               std::to_string(raw.base + i) +
                               " was expected (consecutive numbering)");
      }
      raw.vertices.push_back({src.real(e, 1, "(x)"), src.real(e, 2, "(y)"), src.real(e, 3, "(z)")});
      raw.vertex_lines.push_back(e.number);
    }
    tetgen_expect_end(src, "vertex lines", n);
  }
  {
    LineSource src(ele_path, false);
    if (src.at_end()) src.fail_at_end("empty file, expected the header 'count 4 nattr'");
    const Line& header = src.take();
    if (header.tokens.size() < 2 || header.tokens.size() > 3)
      src.fail(header.number, "expected the header 'count 4 nattr', got " +
                                  std::to_string(header.tokens.size()) + " values");
    const int n = src.count(header, 0, "(tetrahedron count)");
    const long long npe = src.integer(header, 1, "(vertices per tetrahedron)");
    if (npe != 4)
      src.fail(header.number,
               std::to_string(npe) + " vertices per tetrahedron, only 4 is supported");
    const int nattr = header.tokens.size() > 2 ? src.count(header, 2, "(attribute count)") : 0;
    const std::size_t width = 5 + static_cast<std::size_t>(nattr);
    reserve_for(raw, -1, n);
    for (int i = 0; i < n; ++i) {
      const Line& e = tetgen_entry(src, "tetrahedra", i, n, header.number);
      if (e.tokens.size() != width)
        src.fail(e.number, "expected " + std::to_string(width) + " values (index v1 v2 v3 v4" +
                               (nattr > 0 ? " attributes" : "") + "), got " +
                               std::to_string(e.tokens.size()));
      const long long index = src.integer(e, 0, "(tetrahedron index)");
      if (index != raw.base + i)
        src.fail(e.number, "tetrahedron index " + std::to_string(index) + " where " +
                               std::to_string(raw.base + i) + " was expected (numbering from " +
                               std::to_string(raw.base) + " as in " + node_path + ")");
      std::array<long long, 4> t{};
      for (std::size_t a = 0; a < 4; ++a) t[a] = src.integer(e, a + 1, "(vertex index)");
      raw.tets.push_back(t);
      raw.tet_labels.push_back(index);
      raw.tet_lines.push_back(e.number);
    }
    tetgen_expect_end(src, "tetrahedron lines", n);
  }
  return raw;
}

// ---------------------------------------------------------------------------------------------
// VTK XML .vtu (ASCII UnstructuredGrid of tetrahedra, as write_vtu writes it)

/// The text of a .vtu file with the few XML look-ups the reader needs; positions are byte
/// offsets, turned into line numbers for messages.
class VtuText {
 public:
  explicit VtuText(const std::string& path) : path_(path) {
    try {
      text_ = io::detail::read_whole_file(path);
    } catch (const io::detail::ReadError& e) {
      throw ReadError{e.message};
    }
  }

  int line_of(std::size_t pos) const {
    return 1 + static_cast<int>(std::count(
                   text_.begin(),
                   text_.begin() + static_cast<std::ptrdiff_t>(std::min(pos, text_.size())), '\n'));
  }
  [[noreturn]] void fail(std::size_t pos, const std::string& what) const {
    throw ReadError{format_error(path_, line_of(pos), what)};
  }

  /// Start of the next "<name" tag (followed by a space, '>' or '/') at or after from, before
  /// `limit`; npos if none.
  std::size_t find_tag(const std::string& name, std::size_t from,
                       std::size_t limit = std::string::npos) const {
    const std::string open = "<" + name;
    for (std::size_t pos = text_.find(open, from); pos != std::string::npos && pos < limit;
         pos = text_.find(open, pos + 1)) {
      const std::size_t after = pos + open.size();
      if (after < text_.size() && (std::isspace(static_cast<unsigned char>(text_[after])) ||
                                   text_[after] == '>' || text_[after] == '/'))
        return pos;
    }
    return std::string::npos;
  }
  /// Position just after the '>' closing the tag that starts at pos.
  std::size_t tag_end(std::size_t pos) const {
    const std::size_t close = text_.find('>', pos);
    if (close == std::string::npos) fail(pos, "unterminated XML tag (truncated file?)");
    return close + 1;
  }
  /// Start of the closing "</name>" after from.
  std::size_t find_close(const std::string& name, std::size_t from, std::size_t open_pos) const {
    const std::size_t pos = text_.find("</" + name, from);
    if (pos == std::string::npos)
      fail(open_pos, "<" + name + "> is never closed (truncated file?)");
    return pos;
  }
  /// Value of attribute `name` in the tag starting at pos, if present.
  std::optional<std::string> attribute(std::size_t pos, const std::string& name) const {
    const std::size_t end = tag_end(pos);
    const std::string tag = text_.substr(pos, end - pos);
    for (std::size_t at = tag.find(name + "="); at != std::string::npos;
         at = tag.find(name + "=", at + 1)) {
      if (at == 0 || !std::isspace(static_cast<unsigned char>(tag[at - 1]))) continue;
      const std::size_t quote = at + name.size() + 1;
      if (quote >= tag.size() || (tag[quote] != '"' && tag[quote] != '\'')) continue;
      const std::size_t close = tag.find(tag[quote], quote + 1);
      if (close == std::string::npos) fail(pos, "unterminated attribute " + name);
      return tag.substr(quote + 1, close - quote - 1);
    }
    return std::nullopt;
  }
  int count_attribute(std::size_t pos, const std::string& tag, const std::string& name) const {
    const auto value = attribute(pos, name);
    if (!value) fail(pos, "<" + tag + "> has no " + name + " attribute");
    long long n = 0;
    if (!parse_integer(*value, n) || n < 0 || n > INT_MAX)
      fail(pos, "invalid " + name + " " + quoted(*value));
    return static_cast<int>(n);
  }

  struct Token {
    std::string text;
    int line = 0;
  };
  /// The whitespace-separated tokens of an ASCII <DataArray> starting at pos (its format must be
  /// ascii) and the position after its closing tag.
  std::vector<Token> data_array(std::size_t pos, const std::string& what,
                                std::size_t* after) const {
    const auto format = attribute(pos, "format");
    if (format && *format != "ascii")
      fail(pos, what + " DataArray has format=\"" + *format +
                    "\"; only ASCII .vtu files (format=\"ascii\") are read");
    const std::size_t begin = tag_end(pos);
    if (text_[begin - 2] == '/') fail(pos, what + " DataArray is empty");
    const std::size_t end = find_close("DataArray", begin, pos);
    std::vector<Token> tokens;
    int line = line_of(begin);
    for (std::size_t i = begin; i < end;) {
      const char c = text_[i];
      if (c == '\n') ++line;
      if (std::isspace(static_cast<unsigned char>(c))) {
        ++i;
        continue;
      }
      std::size_t j = i;
      while (j < end && !std::isspace(static_cast<unsigned char>(text_[j]))) ++j;
      tokens.push_back({text_.substr(i, j - i), line});
      i = j;
    }
    *after = tag_end(end);
    return tokens;
  }

  const std::string& text() const { return text_; }

 private:
  std::string path_;
  std::string text_;
};

RawMesh read_vtu(const std::string& path) {
  const VtuText vtu(path);
  RawMesh raw;
  raw.vertex_file = raw.tet_file = path;
  raw.base = 0;
  const std::size_t file_pos = vtu.find_tag("VTKFile", 0);
  if (file_pos == std::string::npos) vtu.fail(0, "no <VTKFile> element (not a VTK XML file)");
  const auto type = vtu.attribute(file_pos, "type");
  if (!type || *type != "UnstructuredGrid")
    vtu.fail(file_pos,
             "VTKFile type " + quoted(type.value_or("(none)")) + ", only UnstructuredGrid is read");
  if (vtu.attribute(file_pos, "compressor"))
    vtu.fail(file_pos, "compressed .vtu files are not read (write ASCII)");
  const std::size_t piece = vtu.find_tag("Piece", file_pos);
  if (piece == std::string::npos) vtu.fail(file_pos, "no <Piece> element");
  if (vtu.find_tag("Piece", piece + 1) != std::string::npos)
    vtu.fail(vtu.find_tag("Piece", piece + 1), "a second <Piece>; only one piece is read");
  const int num_points = vtu.count_attribute(piece, "Piece", "NumberOfPoints");
  const int num_cells = vtu.count_attribute(piece, "Piece", "NumberOfCells");
  const std::size_t piece_end = vtu.find_close("Piece", piece, piece);

  // Points: one Float64/Float32 DataArray with 3 components.
  const std::size_t points = vtu.find_tag("Points", piece, piece_end);
  if (points == std::string::npos) vtu.fail(piece, "<Piece> has no <Points>");
  const std::size_t points_array = vtu.find_tag("DataArray", points, piece_end);
  if (points_array == std::string::npos) vtu.fail(points, "<Points> has no <DataArray>");
  if (const auto nc = vtu.attribute(points_array, "NumberOfComponents"); nc && *nc != "3")
    vtu.fail(points_array,
             "Points DataArray has NumberOfComponents=" + quoted(*nc) + ", expected 3");
  std::size_t after = 0;
  const auto coordinates = vtu.data_array(points_array, "Points", &after);
  if (coordinates.size() != 3 * static_cast<std::size_t>(num_points))
    vtu.fail(points_array, "Points DataArray has " + std::to_string(coordinates.size()) +
                               " numbers, expected 3 x NumberOfPoints = " +
                               std::to_string(3 * static_cast<long long>(num_points)));
  reserve_for(raw, num_points, num_cells);
  const auto real = [&](const VtuText::Token& t, const char* what) {
    double v = 0;
    if (!parse_double(t.text, v))
      throw ReadError{format_error(
          path, t.line, std::string("expected a number ") + what + ", got " + quoted(t.text))};
    return v;
  };
  const auto integer = [&](const VtuText::Token& t, const char* what) {
    long long v = 0;
    if (!parse_integer(t.text, v))
      throw ReadError{format_error(
          path, t.line, std::string("expected an integer ") + what + ", got " + quoted(t.text))};
    return v;
  };
  for (std::size_t i = 0; i < static_cast<std::size_t>(num_points); ++i) {
    raw.vertices.push_back({real(coordinates[3 * i], "(x)"), real(coordinates[3 * i + 1], "(y)"),
                            real(coordinates[3 * i + 2], "(z)")});
    raw.vertex_lines.push_back(coordinates[3 * i].line);
  }

  // Cells: connectivity, offsets, types (any order).
  const std::size_t cells = vtu.find_tag("Cells", piece, piece_end);
  if (cells == std::string::npos) vtu.fail(piece, "<Piece> has no <Cells>");
  const std::size_t cells_end = vtu.find_close("Cells", cells, cells);
  std::optional<std::vector<VtuText::Token>> connectivity, offsets, types;
  std::size_t connectivity_pos = 0, offsets_pos = 0, types_pos = 0;
  for (std::size_t pos = vtu.find_tag("DataArray", cells, cells_end); pos != std::string::npos;
       pos = vtu.find_tag("DataArray", after, cells_end)) {
    const std::string name = vtu.attribute(pos, "Name").value_or("");
    if (name == "connectivity") {
      connectivity = vtu.data_array(pos, name, &after);
      connectivity_pos = pos;
    } else if (name == "offsets") {
      offsets = vtu.data_array(pos, name, &after);
      offsets_pos = pos;
    } else if (name == "types") {
      types = vtu.data_array(pos, name, &after);
      types_pos = pos;
    } else {
      after = vtu.tag_end(pos);
    }
  }
  if (!connectivity) vtu.fail(cells, "<Cells> has no connectivity DataArray");
  if (!offsets) vtu.fail(cells, "<Cells> has no offsets DataArray");
  if (!types) vtu.fail(cells, "<Cells> has no types DataArray");
  const auto n = static_cast<std::size_t>(num_cells);
  if (types->size() != n)
    vtu.fail(types_pos, "types DataArray has " + std::to_string(types->size()) +
                            " values for NumberOfCells = " + std::to_string(n));
  if (offsets->size() != n)
    vtu.fail(offsets_pos, "offsets DataArray has " + std::to_string(offsets->size()) +
                              " values for NumberOfCells = " + std::to_string(n));
  for (std::size_t c = 0; c < n; ++c) {
    const long long cell_type = integer((*types)[c], "(cell type)");
    if (cell_type != 10)
      throw ReadError{format_error(path, (*types)[c].line,
                                   "cell " + std::to_string(c) + " has VTK type " +
                                       std::to_string(cell_type) +
                                       ", only tetrahedra (type 10) are read")};
    const long long offset = integer((*offsets)[c], "(cell offset)");
    if (offset != 4 * static_cast<long long>(c + 1))
      throw ReadError{format_error(path, (*offsets)[c].line,
                                   "cell " + std::to_string(c) + " ends at offset " +
                                       std::to_string(offset) + ", expected " +
                                       std::to_string(4 * (c + 1)) + " (4 vertices per tet)")};
  }
  if (connectivity->size() != 4 * n)
    vtu.fail(connectivity_pos, "connectivity DataArray has " +
                                   std::to_string(connectivity->size()) + " values, expected " +
                                   std::to_string(4 * n) + " (4 per tet)");
  for (std::size_t c = 0; c < n; ++c) {
    std::array<long long, 4> t{};
    for (std::size_t a = 0; a < 4; ++a)
      t[a] = integer((*connectivity)[4 * c + a], "(vertex index)");
    raw.tets.push_back(t);
    raw.tet_labels.push_back(static_cast<long long>(c));
    raw.tet_lines.push_back((*connectivity)[4 * c].line);
  }
  return raw;
}

// ---------------------------------------------------------------------------------------------
// Validation

std::string number(double v) {
  std::ostringstream s;
  s.precision(6);
  s << v;
  return s.str();
}

double signed_volume(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                     const Eigen::Vector3d& d) {
  return (b - a).cross(c - a).dot(d - a) / 6.0;
}

TetMeshReadResult validate(const RawMesh& raw, const TetMeshReadOptions& options) {
  const auto vertex_error = [&](std::size_t i, const std::string& what) {
    return format_error(raw.vertex_file, raw.vertex_lines[i], what);
  };
  const auto tet_error = [&](std::size_t t, const std::string& what) {
    return format_error(raw.tet_file, raw.tet_lines[t],
                        "element " + std::to_string(raw.tet_labels[t]) + " " + what);
  };
  TetMeshReadResult result;
  const auto nv = static_cast<Eigen::Index>(raw.vertices.size());
  const auto nt = static_cast<Eigen::Index>(raw.tets.size());
  if (nt == 0) {
    result.error = raw.tet_file + ": the mesh has no tetrahedra";
    return result;
  }
  TetMesh mesh;
  mesh.vertices.resize(nv, 3);
  for (Eigen::Index i = 0; i < nv; ++i) {
    const auto& v = raw.vertices[static_cast<std::size_t>(i)];
    if (!std::isfinite(v[0]) || !std::isfinite(v[1]) || !std::isfinite(v[2])) {
      result.error =
          vertex_error(static_cast<std::size_t>(i),
                       "vertex " + std::to_string(i + raw.base) + " has a non-finite coordinate (" +
                           number(v[0]) + " " + number(v[1]) + " " + number(v[2]) + ")");
      return result;
    }
    mesh.vertices.row(i) << v[0], v[1], v[2];
  }
  mesh.tets.resize(nt, 4);
  for (Eigen::Index t = 0; t < nt; ++t) {
    const auto ts = static_cast<std::size_t>(t);
    const auto& tet = raw.tets[ts];
    for (int a = 0; a < 4; ++a) {
      const long long local = tet[static_cast<std::size_t>(a)] - raw.base;
      if (local < 0 || local >= nv) {
        result.error =
            tet_error(ts, "references vertex " + std::to_string(tet[static_cast<std::size_t>(a)]) +
                              ", but there are " + std::to_string(nv) + " vertices" +
                              (raw.base == 0 ? " (numbered from 0)" : ""));
        return result;
      }
      mesh.tets(t, a) = static_cast<int>(local);
    }
    for (int a = 0; a < 4; ++a) {
      for (int b = a + 1; b < 4; ++b) {
        if (mesh.tets(t, a) == mesh.tets(t, b)) {
          result.error =
              tet_error(ts, "repeats vertex " + std::to_string(tet[static_cast<std::size_t>(a)]));
          return result;
        }
      }
    }
  }
  const double diag =
      nv > 0 ? (mesh.vertices.colwise().maxCoeff() - mesh.vertices.colwise().minCoeff()).norm()
             : 0.0;
  const double tolerance = 1e-12 * diag * diag * diag;
  std::vector<double> volumes(static_cast<std::size_t>(nt));
  Eigen::Index negative = 0;
  for (Eigen::Index t = 0; t < nt; ++t) {
    const auto ts = static_cast<std::size_t>(t);
    const auto x = [&](int a) -> Eigen::Vector3d {
      return mesh.vertices.row(mesh.tets(t, a)).transpose();
    };
    const double volume = signed_volume(x(0), x(1), x(2), x(3));
    if (std::abs(volume) < tolerance || volume == 0.0) {
      result.error =
          tet_error(ts, "is degenerate (signed volume " + number(volume) +
                            ", below 1e-12 * bbox_diagonal^3 = " + number(tolerance) + ")");
      return result;
    }
    if (volume < 0 && !options.fix_orientation) {
      result.error = tet_error(
          ts,
          "is inverted (signed volume " + number(volume) +
              "); positive orientation is required (fix_orientation swaps two of its vertices)");
      return result;
    }
    volumes[ts] = volume;
    if (volume < 0) ++negative;
  }
  // All tets negative: the file's convention, fixed by swapping two vertices of every tet. Some
  // negative: a folded (tangled) mesh or an inconsistent vertex order; either way the first tet
  // of the minority orientation is named.
  if (negative > 0 && negative < nt) {
    const bool minority_negative = 2 * negative <= nt;
    const Eigen::Index majority = minority_negative ? nt - negative : negative;
    for (Eigen::Index t = 0; t < nt; ++t) {
      const auto ts = static_cast<std::size_t>(t);
      if ((volumes[ts] < 0) != minority_negative) continue;
      result.error = tet_error(
          ts, std::string("is ") + (minority_negative ? "inverted" : "positively oriented") +
                  " (signed volume " + number(volumes[ts]) + ") while " + std::to_string(majority) +
                  " of the " + std::to_string(nt) + " tets are " +
                  (minority_negative ? "positive" : "negative") +
                  ": mixed orientation (a folded mesh or an inconsistent vertex order)");
      return result;
    }
  }
  if (negative == nt) {
    for (Eigen::Index t = 0; t < nt; ++t) std::swap(mesh.tets(t, 2), mesh.tets(t, 3));
    result.flipped_tets = static_cast<int>(nt);
  }
  result.mesh = std::move(mesh);
  return result;
}

bool fail_write(std::string* error, const std::string& message) {
  if (error != nullptr) *error = message;
  return false;
}

/// Checks the tets index existing vertices (writers must not produce unreadable files).
bool check_mesh_for_write(const std::string& path, const TetMesh& mesh, std::string* error) {
  if (mesh.tets.size() > 0 &&
      (mesh.tets.minCoeff() < 0 || mesh.tets.maxCoeff() >= mesh.vertices.rows()))
    return fail_write(error, path + ": cannot write: a tet references a vertex outside 0.." +
                                 std::to_string(mesh.vertices.rows() - 1));
  return true;
}

}  // namespace

TetMeshReadResult read_tet_mesh(const std::string& path, const TetMeshReadOptions& options) {
  try {
    const std::string ext = to_lower(std::filesystem::path(path).extension().string());
    RawMesh raw;
    if (ext == ".mesh") {
      raw = read_medit(path);
    } else if (ext == ".veg") {
      raw = read_veg(path);
    } else if (ext == ".node" || ext == ".ele") {
      raw = read_tetgen(path);
    } else if (ext == ".vtu") {
      raw = read_vtu(path);
    } else {
      TetMeshReadResult result;
      result.error = path + ": unknown tet-mesh extension " +
                     quoted(ext.empty() ? std::string("(none)") : ext) +
                     " (expected .mesh, .veg, .vtu, .node or .ele)";
      return result;
    }
    return validate(raw, options);
  } catch (const ReadError& e) {
    TetMeshReadResult result;
    result.error = e.message;
    return result;
  } catch (const std::bad_alloc&) {
    TetMeshReadResult result;
    result.error = path + ": out of memory while reading";
    return result;
  } catch (const std::exception& e) {
    TetMeshReadResult result;
    result.error = path + ": " + e.what();
    return result;
  } catch (...) {
    TetMeshReadResult result;
    result.error = path + ": unknown error while reading";
    return result;
  }
}

bool write_medit_mesh(const std::string& path, const TetMesh& mesh, std::string* error) {
  try {
    if (!check_mesh_for_write(path, mesh, error)) return false;
    std::ofstream out(path, std::ios::binary);
    if (!out)
      return fail_write(error, path + ": cannot open for writing (" + std::strerror(errno) + ")");
    out.precision(std::numeric_limits<double>::max_digits10);
    out << "MeshVersionFormatted 1\n\nDimension 3\n\nVertices\n" << mesh.vertices.rows() << "\n";
    for (Eigen::Index i = 0; i < mesh.vertices.rows(); ++i)
      out << mesh.vertices(i, 0) << " " << mesh.vertices(i, 1) << " " << mesh.vertices(i, 2)
          << " 0\n";
    out << "\nTetrahedra\n" << mesh.tets.rows() << "\n";
    for (Eigen::Index t = 0; t < mesh.tets.rows(); ++t)
      out << mesh.tets(t, 0) + 1 << " " << mesh.tets(t, 1) + 1 << " " << mesh.tets(t, 2) + 1 << " "
          << mesh.tets(t, 3) + 1 << " 0\n";
    out << "\nEnd\n";
    out.close();
    if (!out) return fail_write(error, path + ": write error");
    return true;
  } catch (const std::exception& e) {
    return fail_write(error, path + ": " + e.what());
  }
}

namespace {
std::string xml_escape(const std::string& s) {
  std::string r;
  for (const char c : s) {
    switch (c) {
      case '&':
        r += "&amp;";
        break;
      case '<':
        r += "&lt;";
        break;
      case '>':
        r += "&gt;";
        break;
      case '"':
        r += "&quot;";
        break;
      case '\'':
        r += "&apos;";
        break;
      default:
        r += c;
    }
  }
  return r;
}
}  // namespace

bool write_vtu(const std::string& path, const TetMesh& mesh, const TetScalarFields& cell_fields,
               std::string* error) {
  TetCellFields fields;
  fields.reserve(cell_fields.size());
  for (const auto& [name, values] : cell_fields) fields.push_back({name, values});
  return write_vtu_cell_fields(path, mesh, fields, error);
}

bool write_vtu_cell_fields(const std::string& path, const TetMesh& mesh,
                           const TetCellFields& cell_fields, std::string* error) {
  return write_vtu_fields(path, mesh, cell_fields, {}, error);
}

bool write_vtu_fields(const std::string& path, const TetMesh& mesh,
                      const TetCellFields& cell_fields, const TetCellFields& point_fields,
                      std::string* error) {
  try {
    if (!check_mesh_for_write(path, mesh, error)) return false;
    const auto check = [&](const TetCellFields& fields, Eigen::Index rows, const char* per) {
      for (const TetCellField& field : fields) {
        if (field.values.rows() != rows)
          return fail_write(error, path + ": cannot write: field '" + field.name + "' has " +
                                       std::to_string(field.values.rows()) + " values for " +
                                       std::to_string(rows) + " " + per);
        if (field.values.cols() < 1)
          return fail_write(error,
                            path + ": cannot write: field '" + field.name + "' has no components");
      }
      return true;
    };
    if (!check(cell_fields, mesh.tets.rows(), "tets") ||
        !check(point_fields, mesh.vertices.rows(), "vertices"))
      return false;
    std::ostringstream out;
    out.imbue(std::locale::classic());
    out.precision(std::numeric_limits<double>::max_digits10);
    const Eigen::Index nv = mesh.vertices.rows(), nt = mesh.tets.rows();
    out << "<?xml version=\"1.0\"?>\n"
        << "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" "
           "header_type=\"UInt64\">\n"
        << "  <UnstructuredGrid>\n"
        << "    <Piece NumberOfPoints=\"" << nv << "\" NumberOfCells=\"" << nt << "\">\n"
        << "      <Points>\n"
        << "        <DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n";
    for (Eigen::Index i = 0; i < nv; ++i)
      out << "          " << mesh.vertices(i, 0) << " " << mesh.vertices(i, 1) << " "
          << mesh.vertices(i, 2) << "\n";
    out << "        </DataArray>\n"
        << "      </Points>\n"
        << "      <Cells>\n"
        << "        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n";
    for (Eigen::Index t = 0; t < nt; ++t)
      out << "          " << mesh.tets(t, 0) << " " << mesh.tets(t, 1) << " " << mesh.tets(t, 2)
          << " " << mesh.tets(t, 3) << "\n";
    out << "        </DataArray>\n"
        << "        <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n";
    for (Eigen::Index t = 0; t < nt; ++t)
      out << (t % 16 == 0 ? "          " : " ") << 4 * (t + 1)
          << (t % 16 == 15 || t + 1 == nt ? "\n" : "");
    out << "        </DataArray>\n"
        << "        <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
    for (Eigen::Index t = 0; t < nt; ++t)
      out << (t % 16 == 0 ? "          " : " ") << 10 << (t % 16 == 15 || t + 1 == nt ? "\n" : "");
    out << "        </DataArray>\n"
        << "      </Cells>\n";
    // One <PointData> or <CellData> section; its Scalars attribute names the active scalar field
    // (the first one-component field).
    const auto section = [&out](const char* tag, const TetCellFields& fields) {
      if (fields.empty()) return;
      std::string active;
      for (const TetCellField& field : fields) {
        if (field.values.cols() == 1) {
          active = field.name;
          break;
        }
      }
      out << "      <" << tag;
      if (!active.empty()) out << " Scalars=\"" << xml_escape(active) << "\"";
      out << ">\n";
      for (const TetCellField& field : fields) {
        out << "        <DataArray type=\"Float64\" Name=\"" << xml_escape(field.name) << "\"";
        if (field.values.cols() > 1) out << " NumberOfComponents=\"" << field.values.cols() << "\"";
        out << " format=\"ascii\">\n";
        for (Eigen::Index r = 0; r < field.values.rows(); ++r) {
          out << "          " << field.values(r, 0);
          for (Eigen::Index c = 1; c < field.values.cols(); ++c) out << " " << field.values(r, c);
          out << "\n";
        }
        out << "        </DataArray>\n";
      }
      out << "      </" << tag << ">\n";
    };
    section("PointData", point_fields);  // VTK's order: PointData before CellData
    section("CellData", cell_fields);
    out << "    </Piece>\n"
        << "  </UnstructuredGrid>\n"
        << "</VTKFile>\n";
    return io::detail::write_file_atomically(path, out.str(), error);
  } catch (const std::exception& e) {
    return fail_write(error, path + ": " + e.what());
  }
}

}  // namespace sinew::offline
