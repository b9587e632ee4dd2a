#pragma once
/// Sparse Cholesky factorisation A = LLᵀ of a symmetric positive-definite matrix with CHOLMOD
/// (SuiteSparse): symbolic analysis once per sparsity pattern, numeric factorisation many times
/// with new values, and solves for many right-hand sides as one block. Two numeric methods
/// (SparseCholeskyMethod): simplicial (plain loops, no BLAS: the same bits on every x86-64 CPU and
/// thread count) and supernodal on OpenBLAS (shared/reference/performance_facts.md: 3–4x faster
/// than reference BLAS on large meshes, but OpenBLAS picks its kernels by CPU at run time, so the
/// last bits of every factor and solve depend on the machine); by default simplicial for small
/// factors and supernodal for large ones (kAuto). METIS ordering has
/// ~23% less fill than AMD; a 900-column block solve is 2–5x faster than 900 single solves.
///
/// Storage: only the upper triangle (row ≤ column) of the given matrix is read; entries below the
/// diagonal are ignored. So both full symmetric storage and upper-triangle-only storage
/// (common::PatternStorage::kUpper) work; lower-triangle-only storage does NOT.
///
/// CHOLMOD's headers stay in sparse_cholesky.cpp (pimpl): nothing else includes cholmod.h.

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace sinew::offline {

/// Fill-reducing ordering of the symbolic analysis.
enum class SparseCholeskyOrdering {
  kMetis,    ///< nested dissection (METIS) only: least fill on 3D meshes
  kAmd,      ///< approximate minimum degree only: faster analysis, more fill
  kCholmod,  ///< CHOLMOD's default strategy (AMD, then METIS if AMD's fill is poor; keeps the best)
};

const char* to_string(SparseCholeskyOrdering ordering);

/// Numeric factorisation and solve method.
enum class SparseCholeskyMethod {
  /// Simplicial when the analysis predicts at most SparseCholeskyOptions::
  /// simplicial_max_factor_nonzeros nonzeros in L, supernodal above: the same answer on every
  /// machine where that costs little, speed where it would cost much. A function of the pattern
  /// alone, so every machine takes the same branch.
  kAuto,
  /// CHOLMOD's simplicial (row-oriented) LLᵀ and solves: no BLAS call, so the result does not
  /// depend on the OpenBLAS kernel the CPU selects (OPENBLAS_CORETYPE) nor on thread counts.
  /// The Gauss–Newton registration amplifies last-bit differences into different outcomes
  /// (sub-verse013: 0.837 mm with OpenBLAS's SkylakeX kernels, 0.797 mm with Haswell's). Cost
  /// against supernodal on this machine (box tet meshes, vector Laplacian, METIS): factorisation
  /// 3x at 6k tets (nnz(L) 0.76 M: 0.11 s), 7.5x at 21k (4.0 M: 1.6 s), 16x at 49k (13 M: 12.6 s);
  /// a 480-column solve 2.8x, 3.3x, 3.5x.
  kSimplicial,
  /// CHOLMOD's supernodal LLᵀ on OpenBLAS (dense BLAS/LAPACK on the supernodes): fast on large
  /// factors, rounding that depends on the CPU's BLAS kernels.
  kSupernodal,
};

const char* to_string(SparseCholeskyMethod method);

struct SparseCholeskyOptions {
  SparseCholeskyOrdering ordering = SparseCholeskyOrdering::kMetis;
  SparseCholeskyMethod method = SparseCholeskyMethod::kAuto;
  /// kAuto's switch: the largest nnz(L) factorised simplicially. 1e6: the 4,227-tet vertebra
  /// meshes, the 5,184-tet Fig. 4 beam and the tools' small cases are reproducible at no
  /// measurable cost in their runs; the 12,288-tet ground-truth bar and larger meshes (the
  /// 40k-tet liver) keep supernodal speed and depend on the machine's BLAS kernels.
  double simplicial_max_factor_nonzeros = 1e6;
};

enum class SparseCholeskyStatus {
  kOk,
  kNotAnalysed,          ///< factorise() before a successful analyse()
  kNotFactorised,        ///< solve() before a successful factorise()
  kInvalidInput,         ///< not square, empty, or a size that does not match
  kPatternMismatch,      ///< factorise() with a pattern other than the analysed one
  kNotPositiveDefinite,  ///< the numeric factorisation hit a non-positive pivot (see failed_column)
  kOutOfMemory,          ///< CHOLMOD ran out of memory
  kCholmodError,         ///< any other CHOLMOD error (e.g. METIS not available)
};

const char* to_string(SparseCholeskyStatus status);

/// RAII wrapper of one CHOLMOD workspace and one factor. Movable, not copyable.
class SparseCholesky {
 public:
  explicit SparseCholesky(const SparseCholeskyOptions& options = {});
  ~SparseCholesky();
  SparseCholesky(SparseCholesky&&) noexcept;
  SparseCholesky& operator=(SparseCholesky&&) noexcept;
  SparseCholesky(const SparseCholesky&) = delete;
  SparseCholesky& operator=(const SparseCholesky&) = delete;

  /// Symbolic analysis (ordering, supernodes, sizes of L) of the pattern of A (n x n, upper
  /// triangle read; values ignored). Keeps a copy of the pattern so that factorise() can check it.
  /// Discards any previous factor.
  SparseCholeskyStatus analyse(const Eigen::SparseMatrix<double>& A);

  /// Numeric factorisation of A, whose pattern must be the analysed one (same sizes, same stored
  /// entries). Reuses the symbolic analysis. On kNotPositiveDefinite, factor_minor() /
  /// failed_column() tell where the non-positive pivot was, and solve() is refused until a later
  /// factorise() succeeds.
  SparseCholeskyStatus factorise(const Eigen::SparseMatrix<double>& A);

  /// analyse() then factorise().
  SparseCholeskyStatus compute(const Eigen::SparseMatrix<double>& A);

  /// Solves A X = B for all columns of B (n x k) at once, as one block. solution must already be
  /// n x k (a VectorXd binds for k = 1) and may not alias rhs. After the first call with a given
  /// k, no allocation happens inside CHOLMOD (its workspaces are kept).
  SparseCholeskyStatus solve(const Eigen::Ref<const Eigen::MatrixXd>& rhs,
                             Eigen::Ref<Eigen::MatrixXd> solution);

  /// The solve workspace of one thread (a CHOLMOD workspace and its dense buffers).
  class SolveWorkspace {
   public:
    SolveWorkspace();
    ~SolveWorkspace();
    SolveWorkspace(SolveWorkspace&&) noexcept;
    SolveWorkspace& operator=(SolveWorkspace&&) noexcept;
    SolveWorkspace(const SolveWorkspace&) = delete;
    SolveWorkspace& operator=(const SolveWorkspace&) = delete;

   private:
    friend class SparseCholesky;
    struct Impl;
    std::unique_ptr<Impl> impl_;
  };

  /// solve() with the caller's workspace: the factor is only read, so several threads may solve
  /// with one factor at once, each with its own workspace (the multi-right-hand-side solves of
  /// the Woodbury step split their column blocks this way).
  SparseCholeskyStatus solve(const Eigen::Ref<const Eigen::MatrixXd>& rhs,
                             Eigen::Ref<Eigen::MatrixXd> solution, SolveWorkspace& workspace) const;

  /// solve() for many right-hand sides: blocks of at most block_columns columns spread over
  /// threads (0 = the CPUs this process may use), each thread with a workspace of its own kept in
  /// this object. Same shapes and results as solve() (to rounding).
  SparseCholeskyStatus solve_in_blocks(const Eigen::Ref<const Eigen::MatrixXd>& rhs,
                                       Eigen::Ref<Eigen::MatrixXd> solution,
                                       Eigen::Index block_columns = 64, int threads = 0);

  bool analysed() const;
  bool factorised() const;
  /// Size n of the analysed matrix (0 before analyse()).
  Eigen::Index rows() const;
  /// Number of nonzeros of L for the analysed pattern (CHOLMOD's count of the chosen ordering),
  /// std::nullopt before analyse().
  std::optional<double> factor_nonzeros() const;
  /// CHOLMOD's L->minor after a factorise() that returned kNotPositiveDefinite: the number of
  /// columns of the permuted matrix PAPᵀ factorised before the non-positive pivot.
  std::optional<Eigen::Index> factor_minor() const;
  /// The same column in A's own numbering (P⁻¹ applied to factor_minor()).
  std::optional<Eigen::Index> failed_column() const;
  /// Wall-clock seconds of the last analyse() / the last factorise() / all factorise() calls.
  double analysis_seconds() const;
  double factorisation_seconds() const;
  double total_factorisation_seconds() const;
  int num_factorisations() const;
  /// The numeric method of the analysed factor (kSimplicial or kSupernodal; kAuto resolved),
  /// after analyse().
  std::optional<SparseCholeskyMethod> method_used() const;
  /// The ordering CHOLMOD actually used (CHOLMOD's own name: "metis", "amd", "natural", ...),
  /// after analyse().
  std::optional<std::string> ordering_used() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sinew::offline
