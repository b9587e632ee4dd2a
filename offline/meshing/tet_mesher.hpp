#pragma once
/// Tetrahedral meshing of a closed triangle surface (the template organ surface of seed 003, §4:
/// "we tet-mesh the template surface"), by CGAL Mesh_3 (Delaunay refinement of a polyhedral
/// domain, then optional ODT / Lloyd smoothing, sliver perturbation and sliver exudation).
///
/// CGAL stays inside tet_mesher.cpp (its headers are slow to compile and need -frounding-math);
/// this header depends on Eigen only. Sizes are given as fractions of the diagonal of the input's
/// bounding box, so the same options fit a surface in metres or in millimetres.
///
/// The input surface is checked before meshing (shape, finite coordinates, index range, degenerate
/// faces, every edge shared by exactly two consistently oriented faces, manifold vertices, no
/// self-intersection); an inward-oriented surface is accepted and reported. Output tets are
/// right-handed (positive signed volume); only cells of the complex are kept, unreferenced
/// vertices are dropped and vertices renumbered in order of first use. The result is
/// deterministic for a fixed random_seed (sequential meshing, smoothing bounded by iteration
/// counts, perturbation and exudation run to completion unless a time limit is set).
///
/// Quality with the defaults (ODT, perturbation and exudation to 12°): smallest dihedral angle
/// ≥ ~12° and largest ≤ ~160° on smooth organ-like surfaces (test_tet_mesher: unit icosphere of
/// 1280 faces, ~3000 tets in well under a second).

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "offline/io/tet_mesh_io.hpp"

namespace sinew::offline {

struct TetMesherOptions {
  /// Upper bound on the circumradius of the tets, as a fraction of the bounding-box diagonal of
  /// the input surface; in (0, 1]. Also bounds the surface facets (facet_size) and, with feature
  /// protection, the edges along sharp creases. Halving it gives about 8 times more tets; the
  /// default gives a few thousand tets for a compact, roughly convex (organ-like) shape.
  double cell_size_fraction = 0.06;
  /// Thickness-sized cells (surface input only): at each point the cell and facet size bound is
  /// min(cell_size_fraction·diagonal, thickness / tets_across_thickness), where the thickness is
  /// the chord through the solid along the inward normal at the surface point closest to the
  /// point (a ray cast on the input surface), so thin parts get about this many tets across;
  /// never below min_size_fraction·diagonal. 0 (the default): the uniform bound alone; ≥ 0.
  double tets_across_thickness = 0.0;
  /// Lower bound of the thickness-sized bound, as a fraction of the diagonal; in (0, 1].
  double min_size_fraction = 0.005;
  /// With tets_across_thickness: only parts thinner than this multiple of the surface's median
  /// thickness (area-weighted over its faces) are thickness-sized, the rest gets the uniform
  /// bound (issue 51: a femur is thin everywhere against a cell of 0.08 of its length, and
  /// thickness sizing meshed it 2.5x finer with no part thinner than the rest); 0: every part
  /// (as before); >= 0.
  double thin_fraction_of_median = 0.0;
  /// Upper bound on the distance between a surface facet's circumcentre and its surface Delaunay
  /// ball centre (the approximation error of the surface), as a fraction of the bounding-box
  /// diagonal; in (0, 1]. Smaller values refine the surface more where it is curved.
  double facet_distance_fraction = 0.002;
  /// Lower bound on the angles of the surface facets, degrees; in (0, 30] (CGAL guarantees
  /// termination up to 30°).
  double facet_angle_degrees = 25.0;
  /// Upper bound on the ratio of a tet's circumradius to its shortest edge; ≥ 2 (CGAL guarantees
  /// termination only for ratios ≥ 2). Removes badly shaped tets except slivers, which
  /// perturb/exude target.
  double cell_radius_edge_ratio = 3.0;

  /// Global optimisation by Optimal Delaunay Triangulation smoothing after refinement: better
  /// average shape and easier sliver removal, for a fraction of the refinement time.
  bool odt = true;
  /// Global optimisation by Lloyd smoothing (after ODT if both are on). Usually less effective
  /// against slivers than ODT; off by default.
  bool lloyd = false;
  /// Iterations of ODT / Lloyd (each stops earlier on convergence); in [1, 1000]. An iteration
  /// count (not a time limit) keeps the result deterministic.
  int smoothing_iterations = 20;
  /// Sliver perturbation: moves vertices to raise the smallest dihedral angles towards
  /// sliver_bound_degrees. Needed for a sane smallest angle (without it, slivers of 2-3° remain).
  bool perturb = true;
  /// Sliver exudation: assigns weights to vertices to remove the remaining slivers from the
  /// weighted Delaunay triangulation. Cheap; keep it on.
  bool exude = true;
  /// Target smallest dihedral angle of perturbation and exudation, degrees; in (0, 60). Higher
  /// targets are slower to reach and may not be (perturbation then gives up).
  double sliver_bound_degrees = 12.0;
  /// Wall-clock limit of perturbation and of exudation each, seconds; ≥ 0, 0 = none (default,
  /// deterministic). Perturbation can take minutes when the cells are coarse compared with the
  /// surface refinement; a limit caps that, but when it is reached
  /// (TetMesherSummary::time_limit_reached) the result depends on the machine's speed.
  double optimisation_time_limit_seconds = 0.0;

  /// Detect sharp creases of the input (see feature_angle_degrees) and protect them, so edges
  /// and corners of e.g. a cut bone end are kept. Organ surfaces are smooth: off by default.
  bool protect_sharp_features = false;
  /// Creases sharper than this (angle between the normals of adjacent facets, degrees) are
  /// features when protect_sharp_features is on; in (0, 180).
  double feature_angle_degrees = 60.0;

  /// Seed of the random generator of the mesher (initial points shot on the surface); the output
  /// is the same for the same seed, input and options.
  unsigned int random_seed = 0;
  /// Refinement stops (status kVertexLimitReached) when the triangulation reaches this many
  /// vertices; a guard against fractions far too small for the intended use. In [4, 10⁸].
  long max_vertices = 2'000'000;

  /// Empty when valid; otherwise one line naming the field, its value and the constraint.
  std::optional<std::string> validate() const;
};

enum class TetMesherStatus {
  kOk,
  kInvalidOptions,      ///< TetMesherOptions::validate() failed
  kInvalidSurface,      ///< wrong shapes, index out of range, non-finite or degenerate input
  kOpenSurface,         ///< an edge belongs to one face only (the surface has a hole)
  kNonManifoldSurface,  ///< an edge shared by more than two faces, a pinched vertex, or
                        ///< inconsistently oriented faces
  kSelfIntersecting,    ///< two faces of the surface intersect
  kVertexLimitReached,  ///< refinement hit TetMesherOptions::max_vertices
  kCgalFailed,          ///< CGAL threw (precondition, assertion, allocation); message says what
  kEmptyMesh,           ///< meshing finished but no tet lies inside the surface
};

const char* to_string(TetMesherStatus status);

struct TetMesherSummary {
  TetMesherStatus status = TetMesherStatus::kInvalidOptions;
  /// One line saying what is wrong when status is not kOk (empty when kOk).
  std::string message;

  Eigen::Index input_vertices = 0;  ///< rows of the input vertex matrix
  Eigen::Index input_faces = 0;     ///< rows of the input face matrix
  /// The input faces were oriented inwards (negative enclosed volume); meshing does not depend on
  /// orientation, this is only reported.
  bool input_inward_oriented = false;
  double bounding_box_diagonal = 0.0;  ///< of the input vertices, input units (metres)
  double enclosed_volume = 0.0;        ///< volume enclosed by the input surface, cubic units

  Eigen::Index num_vertices = 0;        ///< vertices of the output tet mesh
  Eigen::Index num_tets = 0;            ///< tets of the output mesh
  Eigen::Index num_boundary_faces = 0;  ///< faces of the output mesh that belong to one tet
  int flipped_tets = 0;     ///< tets whose vertex order was swapped to make them right-handed
  double tet_volume = 0.0;  ///< total volume of the output tets, cubic units

  /// Smallest and largest dihedral angle over all tets, degrees (set when there are tets).
  std::optional<double> min_dihedral_degrees;
  std::optional<double> max_dihedral_degrees;
  /// Radius ratio 3·r_in/R_circ per tet (1 for the regular tet, 0 when flat): smallest and mean.
  std::optional<double> min_radius_ratio;
  std::optional<double> mean_radius_ratio;

  /// Perturbation or exudation stopped on optimisation_time_limit_seconds: the output is then
  /// not reproducible.
  bool time_limit_reached = false;

  double check_seconds = 0.0;    ///< wall-clock time of the input checks (self-intersection too)
  double meshing_seconds = 0.0;  ///< of CGAL: the sum of the phases below and the domain set-up
  double refine_seconds = 0.0;   ///< Delaunay refinement
  double odt_seconds = 0.0;      ///< ODT smoothing
  double lloyd_seconds = 0.0;    ///< Lloyd smoothing
  double perturb_seconds = 0.0;  ///< sliver perturbation
  double exude_seconds = 0.0;    ///< sliver exudation
  double seconds = 0.0;          ///< of the whole call

  bool ok() const { return status == TetMesherStatus::kOk; }
  /// One line: status (or the message), counts, dihedral range, time.
  std::string brief_report() const;
  /// Several lines: every field.
  std::string full_report() const;
};

struct TetMesherResult {
  TetMesh mesh;  ///< empty unless summary.ok()
  TetMesherSummary summary;
};

/// Meshes the solid enclosed by a closed, manifold, non-self-intersecting triangle surface.
/// vertices: #V by 3 (metres, or any length unit: sizes are relative); faces: #F by 3, 0-based
/// vertex indices (either orientation, but consistent). Vertices referenced by no face are
/// ignored. Never throws: failures are reported in summary (status and message).
TetMesherResult make_tet_mesh(const Eigen::Ref<const Eigen::MatrixXd>& vertices,
                              const Eigen::Ref<const Eigen::MatrixXi>& faces,
                              const TetMesherOptions& options = {});

/// Meshes the region of a scalar image where its trilinear interpolation exceeds iso (CGAL's gray
/// image domain): a label mask smoothed to [0, 1] with iso 0.5 gives a sub-voxel surface. values:
/// size.x·size.y·size.z numbers, i fastest; voxel (i, j, k) sits at (i·sx, j·sy, k·sz) (the caller
/// maps that to world coordinates); outside the image counts as 0. Sizes are fractions of the
/// diagonal of the box of the voxels above iso. Never throws; failures are in summary.
TetMesherResult make_tet_mesh_from_image(const std::vector<float>& values,
                                         const Eigen::Vector3i& size,
                                         const Eigen::Vector3d& spacing, double iso,
                                         const TetMesherOptions& options = {});

/// Shape quality of a tet mesh (the output's, or a deformed mesh's: seed 003 Fig. 17).
struct TetMeshQuality {
  double min_dihedral_degrees = 0.0;
  double max_dihedral_degrees = 0.0;
  double min_radius_ratio = 0.0;  ///< 3·r_in/R_circ, 1 for the regular tet
  double mean_radius_ratio = 0.0;
  double volume = 0.0;    ///< total signed volume
  int inverted_tets = 0;  ///< tets with signed volume ≤ 0
};
TetMeshQuality tet_mesh_quality(const TetMesh& mesh);

}  // namespace sinew::offline
