#pragma once
/// The plastic-strain Laplacian of seed 003 (appendix A, eqs. 29–31): the combinatorial Laplacian
/// of the tet adjacency graph (tets are adjacent when they share a face),
///   L^sc(i, i) = number of adjacent tets,  L^sc(i, j) = −1 for adjacent i ≠ j,  0 otherwise,
/// 6-expanded to act on the plastic state s (eq. 30): component k of every tet is smoothed by
/// w_k·L^sc, with w = (1, √2, √2, 1, √2, 1) because the off-diagonal components s1, s2, s4 (the
/// paper's s2, s3, s5) each control two entries of the symmetric Fp; then ‖L s‖² = Σ_k w_k² ‖L^sc
/// s_k‖² is ‖L^sc applied to Fp entrywise‖²_F.
///
/// Layout: s is tet-major (offline/plastic/plastic_strain.hpp), so L = L^sc ⊗ diag(w), i.e.
/// L(6i + k, 6j + k) = w_k·L^sc(i, j). Appendix A writes s component-major; the matrices are the
/// same up to that permutation. L is symmetric positive semi-definite; on a connected mesh its
/// nullspace is spanned by the six ψ_k (all ones in component k over all tets, divided by √m).

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <array>
#include <optional>
#include <string>

#include "common/fem/sparse_assembly.hpp"

namespace sinew::offline {

/// w_k of eq. 30: √2 for the off-diagonal components 1, 2, 4 and 1 otherwise.
const std::array<double, 6>& plastic_strain_laplacian_weights();

enum class TetAdjacencyStatus {
  kOk,
  kNegativeIndex,   ///< a tet has a negative vertex index
  kRepeatedVertex,  ///< a tet uses the same vertex twice
};

const char* to_string(TetAdjacencyStatus status);

/// Face adjacency of a tet mesh.
struct TetAdjacency {
  TetAdjacencyStatus status = TetAdjacencyStatus::kOk;
  std::optional<Eigen::Index> bad_tet;  ///< the first offending tet when status is not kOk
  /// One row (i, j), i < j, per pair of tets sharing a face; sorted, no duplicates.
  Eigen::Matrix<int, Eigen::Dynamic, 2> pairs;
  /// Faces shared by more than two tets (a non-manifold mesh); every pair of them is adjacent.
  Eigen::Index non_manifold_faces = 0;
  /// Connected components of the adjacency graph; the nullspace lemma needs exactly 1.
  Eigen::Index num_components = 0;

  bool ok() const { return status == TetAdjacencyStatus::kOk; }
};

/// Tets sharing a face, found by sorting the 4m faces (O(m log m)).
TetAdjacency tet_face_adjacency(const common::TetIndices& tets);

/// L^sc (m x m, eq. 29) from the adjacency of a mesh of num_tets tets (as tet_face_adjacency gives
/// it: every index in pairs is in [0, num_tets)).
Eigen::SparseMatrix<double> scalar_tet_laplacian(const TetAdjacency& adjacency,
                                                 Eigen::Index num_tets);

/// L (6m x 6m, eq. 30, tet-major) from the adjacency of a mesh of num_tets tets (as above).
Eigen::SparseMatrix<double> plastic_strain_laplacian(const TetAdjacency& adjacency,
                                                     Eigen::Index num_tets);

/// The adjacency, L^sc and L of a tet mesh in one call.
struct PlasticStrainLaplacian {
  TetAdjacency adjacency;              ///< check adjacency.ok() and adjacency.num_components
  Eigen::SparseMatrix<double> scalar;  ///< L^sc, m x m (empty unless adjacency.ok())
  Eigen::SparseMatrix<double> matrix;  ///< L, 6m x 6m (empty unless adjacency.ok())

  bool ok() const { return adjacency.ok(); }
};

PlasticStrainLaplacian make_plastic_strain_laplacian(const common::TetIndices& tets);

/// The six orthonormal nullspace vectors ψ_k of L as the columns of a 6m x 6 matrix: column k is
/// 1/√m at entries 6t + k for every tet t and zero elsewhere. Empty (6m x 6 with m = 0) for m = 0.
Eigen::MatrixXd plastic_strain_laplacian_nullspace(Eigen::Index num_tets);

}  // namespace sinew::offline
