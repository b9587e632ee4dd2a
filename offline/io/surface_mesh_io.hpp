#pragma once
/// Triangle-surface readers and writers of the offline registration tool (template organ surface,
/// segmented target surface). Read: Wavefront OBJ, OFF, STL (ASCII and binary) and PLY (ascii,
/// binary_little_endian, binary_big_endian). Written: OBJ and OFF, full double precision,
/// atomically.
///
/// Errors are never thrown: every failure is ONE line naming the file and where it went wrong:
///   text formats    "file:line: what is wrong"        e.g. bunny.obj:812: face references vertex
///                                                          5000, but there are 4214 vertices
///   binary formats  "file: byte N: what is wrong"     e.g. femur.stl: byte 684: facet 12 has a
///                                                          non-finite coordinate (nan 0 1)
///   no position     "file: what is wrong"             unknown extension, unreadable, empty mesh
///
/// Polygons with more than 3 corners (OBJ, OFF, PLY) are fan-triangulated: (v0, vi, vi+1) for
/// i = 1..n-2, which is exact for convex planar polygons only (counted in
/// SurfaceMeshReadResult::polygons_triangulated). Faces repeating a vertex index are an error
/// (SurfaceMeshReadOptions::drop_degenerate_faces drops them instead). Faces whose corners are
/// distinct but collinear (zero area) are kept. Unreferenced vertices are kept.

#include <Eigen/Core>
#include <optional>
#include <string>

namespace sinew::offline::io {

/// An indexed triangle surface.
struct SurfaceMesh {
  Eigen::MatrixXd vertices;   ///< #V by 3, file units (usually millimetres for scan data)
  Eigen::MatrixXi triangles;  ///< #F by 3, 0-based vertex indices, orientation as in the file
};

struct SurfaceMeshReadOptions {
  /// Drop faces that repeat a vertex index (counted in SurfaceMeshReadResult::dropped_faces)
  /// instead of reporting the first one as an error. STL facets collapse this way when two
  /// corners are bitwise equal; exporters of scan segmentations sometimes write such slivers.
  bool drop_degenerate_faces = false;
};

struct SurfaceMeshReadResult {
  std::optional<SurfaceMesh> mesh;  ///< set on success
  std::string error;                ///< one line (see the file comment) on failure, else empty
  int polygons_triangulated = 0;    ///< faces with more than 3 corners, fan-triangulated
  int dropped_faces = 0;            ///< degenerate faces dropped (drop_degenerate_faces only)
  int merged_stl_corners = 0;       ///< STL only: facet corners merged into an earlier equal vertex
  bool ok() const { return mesh.has_value(); }
};

/// Reads a triangle surface, choosing the format by extension (case-insensitive):
///  - `.obj`: `v x y z [w]` (extra values such as vertex colours are ignored) and `f` with
///    `i`, `i/t`, `i//n` or `i/t/n` corners, 1-based, negative = relative to the vertices defined
///    so far (-1 is the last one). vt, vn, l, p, g, o, s, usemtl, mtllib are ignored.
///  - `.off`: header `OFF` (also COFF, NOFF, CNOFF, STOFF...; 3D only, not `OFF BINARY`), counts
///    "nv nf ne" on the header line or the next, then vertices (first 3 values used) and faces
///    "n i1 .. in [colour]", 0-based. '#' starts a comment.
///  - `.stl`: binary when the file size is exactly 84 + 50·n (n = facet count at byte 80), even
///    if it starts with "solid"; ASCII otherwise (must then start with "solid"). Corners with
///    bitwise-equal coordinates (+0 and -0 equal) are merged into one vertex, in order of first
///    appearance; facet normals and attribute bytes are ignored.
///  - `.ply`: ascii, binary_little_endian or binary_big_endian 1.0. Element "vertex" with
///    properties x, y, z (any scalar type; others skipped); element "face" with a list property
///    "vertex_indices" (or "vertex_index"), count and index of any integer type. Other elements
///    and properties are skipped; scalar types: char/int8, uchar/uint8, short/int16,
///    ushort/uint16, int/int32, uint/uint32, float/float32, double/float64.
SurfaceMeshReadResult read_surface_mesh(const std::string& path,
                                        const SurfaceMeshReadOptions& options = {});

/// Topology and volume of a surface, for deciding whether it can be tet-meshed as it is.
struct SurfaceCheck {
  int vertices = 0, triangles = 0;
  int edges = 0;                  ///< distinct undirected edges
  int boundary_edges = 0;         ///< edges used by exactly one triangle (holes)
  int non_manifold_edges = 0;     ///< edges used by three or more triangles
  int inconsistent_edges = 0;     ///< edges used by two triangles in the same direction
  int degenerate_triangles = 0;   ///< triangles repeating a vertex index (not counted as edges)
  int unreferenced_vertices = 0;  ///< vertices used by no triangle (harmless for meshing)
  /// Σ (a·(b×c))/6 over the triangles (relative to the bounding-box centre, for precision), in
  /// file units³. The enclosed volume, positive when the triangles are counter-clockwise seen from
  /// outside (normals outward); only meaningful when closed_manifold().
  double signed_volume = 0.0;

  /// Every edge is shared by exactly two triangles (no holes, no fins).
  bool closed() const { return boundary_edges == 0 && non_manifold_edges == 0; }
  /// Closed, consistently oriented and without degenerate triangles: what a tet mesher needs
  /// (non-manifold vertices, where two sheets touch at a single vertex, are not detected).
  bool closed_manifold() const {
    return triangles > 0 && closed() && inconsistent_edges == 0 && degenerate_triangles == 0;
  }
  /// One line, e.g. "closed manifold: 1622 vertices, 3240 triangles, 4860 edges, volume 1.2e5"
  /// or "not closed: 60 boundary edges, 0 non-manifold edges, 0 inconsistently oriented edges...".
  std::string report() const;
};

/// Counts edges by use and computes the signed volume (see SurfaceCheck). Triangles must index
/// existing vertices.
SurfaceCheck check_surface(const SurfaceMesh& mesh);

/// Writes a Wavefront OBJ ("v x y z" with %.17g, "f a b c" 1-based). Atomic: written to a
/// temporary file next to `path`, then renamed, so a failure never leaves a partial file. Returns
/// false and sets *error (if given) to one line on failure.
bool write_obj(const std::string& path, const SurfaceMesh& mesh, std::string* error = nullptr);

/// Writes an OFF ("OFF", "nv nf 0", vertices with %.17g, "3 a b c" 0-based). Atomic like write_obj.
bool write_off(const std::string& path, const SurfaceMesh& mesh, std::string* error = nullptr);

/// Writes a binary STL (float32 facets with their unit normals; the vertices are repeated per
/// facet, as STL has no shared vertices). Atomic like write_obj.
bool write_stl(const std::string& path, const SurfaceMesh& mesh, std::string* error = nullptr);

/// Writes an ASCII PLY ("element vertex" as double x y z, "element face" as vertex_indices).
/// Atomic like write_obj.
bool write_ply(const std::string& path, const SurfaceMesh& mesh, std::string* error = nullptr);

/// Writes in the format named by the path's extension (.obj, .off, .stl, .ply; case-insensitive).
bool write_surface_mesh(const std::string& path, const SurfaceMesh& mesh,
                        std::string* error = nullptr);

}  // namespace sinew::offline::io
