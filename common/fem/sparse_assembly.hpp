#pragma once
/// Sparse assembly of element matrices and vectors for meshes whose elements have k vertices with
/// 3 dofs each (tetrahedra: k = 4, 12x12 element matrices).
///
/// The pattern is analysed ONCE (analyse): the union of all element blocks becomes a compressed
/// column-major Eigen::SparseMatrix<double>, and a scatter map records, for every element and
/// every entry of its (3k)x(3k) matrix, the index into matrix().valuePtr() that the entry adds to.
/// assemble() then only zeroes the values and adds through the map: no allocation, no search. The
/// sparsity and the arrays of the matrix never change after analyse(), so solvers may keep a
/// symbolic factorisation.
///
/// Dof layout: vertex v owns global dofs 3v, 3v+1, 3v+2 (x, y, z); local dof 3a+d of an element
/// is dof d of its a-th vertex (the vertex-major element layout of common/fem/tet4.hpp).

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <optional>
#include <vector>

namespace sinew::common {

/// Tetrahedra as rows of four vertex indices (#T by 4).
using TetIndices = Eigen::Matrix<int, Eigen::Dynamic, 4>;

/// Which part of the (symmetric) global matrix is stored.
enum class PatternStorage {
  kFull,   ///< every entry (for general solvers and products)
  kUpper,  ///< entries with row ≤ column only; use matrix().selfadjointView<Eigen::Upper>()
};

enum class AssemblyStatus {
  kOk,
  kNotAnalysed,        ///< analyse() has not succeeded yet
  kInvalidDimensions,  ///< negative vertex count, zero vertices per element, or wrong input shape
  kIndexOutOfRange,    ///< an element refers to a vertex outside [0, num_vertices)
};

const char* to_string(AssemblyStatus status);

/// Stacks #V by 3 positions (rows are vertices) into the 3#V dof vector [x0, y0, z0, x1, ...].
Eigen::VectorXd to_dof_vector(const Eigen::Ref<const Eigen::MatrixXd>& positions);

/// Inverse of to_dof_vector: 3#V dofs to #V by 3 positions (dofs.size() must be a multiple of 3).
Eigen::MatrixXd to_positions(const Eigen::Ref<const Eigen::VectorXd>& dofs);

class SparseAssembly {
 public:
  static constexpr int kDofsPerVertex = 3;

  /// Analyses the pattern of a mesh: elements is #E by k (vertex indices in [0, num_vertices)).
  /// Allocates the matrix and the scatter map; everything later reuses them. On failure the
  /// object is left empty (status() tells why, bad_element() which element if applicable).
  AssemblyStatus analyse(const Eigen::Ref<const Eigen::MatrixXi>& elements,
                         Eigen::Index num_vertices, PatternStorage storage = PatternStorage::kFull);

  AssemblyStatus status() const { return status_; }
  /// The first element with an out-of-range vertex index, when status() is kIndexOutOfRange.
  std::optional<Eigen::Index> bad_element() const { return bad_element_; }

  Eigen::Index num_elements() const { return elements_.rows(); }
  int vertices_per_element() const { return static_cast<int>(elements_.cols()); }
  /// Size of one element matrix, 3k.
  int element_dofs() const { return kDofsPerVertex * vertices_per_element(); }
  /// Size of the global matrix, 3#V.
  Eigen::Index num_dofs() const { return kDofsPerVertex * num_vertices_; }
  PatternStorage storage() const { return storage_; }
  const Eigen::MatrixXi& elements() const { return elements_; }

  /// The assembled matrix (3#V by 3#V, compressed, column-major). Its pattern, nonZeros() and
  /// array pointers are fixed by analyse().
  const Eigen::SparseMatrix<double>& matrix() const { return matrix_; }

  /// Zeroes the values of matrix() (keeps the pattern). No allocation.
  void set_zero();

  /// Adds the (3k)x(3k) matrix of element e into matrix() through the scatter map. With kUpper
  /// storage only the entries that land on or above the diagonal are added, so the element
  /// matrix must be symmetric. No allocation, no search; sizes are checked by assertions only.
  void add_element_matrix(Eigen::Index e, const Eigen::Ref<const Eigen::MatrixXd>& element_matrix);

  /// set_zero() then add_element_matrix() for every element. element_matrices is (3k) by
  /// (3k·#E): element e's matrix is the block of columns [3k·e, 3k·(e+1)). Returns kOk, or
  /// kNotAnalysed / kInvalidDimensions (then nothing is changed). No allocation.
  AssemblyStatus assemble(const Eigen::Ref<const Eigen::MatrixXd>& element_matrices);

  /// Adds the 3k-vector of element e into the 3#V global vector. No allocation.
  void add_element_vector(Eigen::Index e, const Eigen::Ref<const Eigen::VectorXd>& element_vector,
                          Eigen::Ref<Eigen::VectorXd> global) const;

  /// Sets global (3#V) to the sum of the element vectors, the columns of element_vectors (3k by
  /// #E). Returns kOk, or kNotAnalysed / kInvalidDimensions (then nothing is changed).
  AssemblyStatus assemble_vector(const Eigen::Ref<const Eigen::MatrixXd>& element_vectors,
                                 Eigen::Ref<Eigen::VectorXd> global) const;

 private:
  using StorageIndex = Eigen::SparseMatrix<double>::StorageIndex;
  // Marks a local entry that is not stored (below the diagonal with kUpper storage).
  static constexpr StorageIndex kNotStored = -1;

  AssemblyStatus status_ = AssemblyStatus::kNotAnalysed;
  std::optional<Eigen::Index> bad_element_;
  Eigen::MatrixXi elements_;
  Eigen::Index num_vertices_ = 0;
  PatternStorage storage_ = PatternStorage::kFull;
  Eigen::SparseMatrix<double> matrix_;
  // scatter_[e·(3k)² + r + 3k·c] = index into matrix_.valuePtr() of local entry (r, c) of e.
  std::vector<StorageIndex> scatter_;
};

}  // namespace sinew::common
