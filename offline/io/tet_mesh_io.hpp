#pragma once
/// Tet-mesh readers and writers of the offline registration tool: Medit `.mesh` (ASCII), VegaFEM
/// `.veg` (ASCII), TetGen `.node`/`.ele` and VTK XML `.vtu` (ASCII UnstructuredGrid of tets, as
/// write_vtu and sinew-register's result.vtu) are read directly; Medit `.mesh` and `.vtu` (for
/// ParaView) are written.
///
/// Errors are never thrown: every failure is reported as ONE line "file:line: what is wrong"
/// (just "file: what is wrong" when no line applies: unknown extension, unreadable file), e.g.
///   box.veg:12: element 7 references vertex 513, but there are 512 vertices
///
/// After parsing, the mesh is validated: entry counts match the headers, element indices are in
/// range, coordinates are finite, no tet repeats a vertex, and no tet is degenerate
/// (|V| < 1e-12 · bbox_diagonal³). A mesh whose tets are ALL negatively oriented (a file
/// convention) is fixed by swapping the last two vertices of every tet
/// (TetMeshReadOptions::fix_orientation, default; counted in TetMeshReadResult::flipped_tets) or
/// reported as an error. Mixed orientation (some tets negative, some positive: a folded mesh or
/// an inconsistent vertex order) is always an error naming the first tet of the minority sign:
///   liver.veg:40: element 5 is inverted (signed volume -0.0026) while 47 of the 48 tets are
///   positive: mixed orientation (a folded mesh or an inconsistent vertex order)

#include <Eigen/Core>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "offline/meshing/tet_mesh.hpp"

namespace sinew::offline {

struct TetMeshReadOptions {
  /// When every tet is negatively oriented: swap two vertices of each (true) or report the first
  /// one as an error. Mixed orientation is an error either way.
  bool fix_orientation = true;
};

struct TetMeshReadResult {
  std::optional<TetMesh> mesh;  ///< set on success
  std::string error;            ///< one line "file:line: message" on failure, empty on success
  int flipped_tets = 0;         ///< tets whose orientation was fixed (fix_orientation only)
  bool ok() const { return mesh.has_value(); }
};

/// Reads a tet mesh, dispatching on the extension (case-insensitive): `.mesh` (Medit ASCII:
/// Vertices and Tetrahedra sections, 1-based, one reference label per entry; other sections are
/// ignored), `.veg` (VegaFEM: *VERTICES and *ELEMENTS/TET; other sections are ignored), `.node` or
/// `.ele` (TetGen: both "<base>.node" and "<base>.ele" are read; numbering from 0 or 1, taken from
/// the first vertex index), `.vtu` (VTK XML UnstructuredGrid, one Piece, format="ascii" DataArrays:
/// Points with 3 components, Cells connectivity/offsets/types with every type 10 = VTK_TETRA;
/// point and cell data are ignored; binary, appended and compressed files are reported).
TetMeshReadResult read_tet_mesh(const std::string& path, const TetMeshReadOptions& options = {});

/// Per-tet scalar fields for write_vtu: (name, one value per tet).
using TetScalarFields = std::vector<std::pair<std::string, Eigen::VectorXd>>;

/// A per-tet field with one or more components for write_vtu: values is #T by k (k = 1 scalar,
/// 3 vector, 9 tensor in row-major order as ParaView reads it).
struct TetCellField {
  std::string name;
  Eigen::MatrixXd values;
};
using TetCellFields = std::vector<TetCellField>;

/// Writes a Medit ASCII `.mesh` (MeshVersionFormatted 1, Dimension 3, Vertices, Tetrahedra; labels
/// 0; full double precision). Returns false and sets *error (if given) on failure.
bool write_medit_mesh(const std::string& path, const TetMesh& mesh, std::string* error = nullptr);

/// Writes an ASCII VTK XML UnstructuredGrid (`.vtu`): Points, Cells (connectivity, offsets,
/// types = 10, VTK_TETRA) and one CellData Float64 DataArray per field. Each field must have one
/// value per tet. Atomic (temporary file + rename). Returns false and sets *error (if given) on
/// failure.
bool write_vtu(const std::string& path, const TetMesh& mesh,
               const TetScalarFields& cell_fields = {}, std::string* error = nullptr);

/// write_vtu with multi-component cell data: one CellData Float64 DataArray per field, with
/// NumberOfComponents = values.cols() (written when > 1). Atomic like write_vtu. (A name of its
/// own: a braced {{"name", values}} list would be ambiguous between two write_vtu overloads.)
bool write_vtu_cell_fields(const std::string& path, const TetMesh& mesh,
                           const TetCellFields& cell_fields, std::string* error = nullptr);

/// write_vtu_cell_fields plus per-vertex fields (PointData, #V rows each; the same struct, read
/// "vertex" for "tet"), for ParaView's per-vertex colouring. Atomic like write_vtu.
bool write_vtu_fields(const std::string& path, const TetMesh& mesh,
                      const TetCellFields& cell_fields, const TetCellFields& point_fields,
                      std::string* error = nullptr);

}  // namespace sinew::offline
