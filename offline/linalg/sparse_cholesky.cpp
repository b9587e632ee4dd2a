#include "offline/linalg/sparse_cholesky.hpp"

#include "common/timing.hpp"
#include "offline/detail/column_blocks.hpp"

#include <cholmod.h>

#include <algorithm>
#include <chrono>
#include <utility>
#include <vector>

namespace sinew::offline {
namespace {

using Clock = std::chrono::steady_clock;

using common::seconds_since;

const char* cholmod_ordering_name(int ordering) {
  switch (ordering) {
    case CHOLMOD_NATURAL:
      return "natural";
    case CHOLMOD_GIVEN:
      return "given";
    case CHOLMOD_AMD:
      return "amd";
    case CHOLMOD_METIS:
      return "metis";
    case CHOLMOD_NESDIS:
      return "nesdis";
    case CHOLMOD_COLAMD:
      return "colamd";
    case CHOLMOD_POSTORDERED:
      return "postordered";
  }
  return "unknown";
}

}  // namespace

const char* to_string(SparseCholeskyOrdering ordering) {
  switch (ordering) {
    case SparseCholeskyOrdering::kMetis:
      return "metis";
    case SparseCholeskyOrdering::kAmd:
      return "amd";
    case SparseCholeskyOrdering::kCholmod:
      return "cholmod-default";
  }
  return "unknown";
}

const char* to_string(SparseCholeskyMethod method) {
  switch (method) {
    case SparseCholeskyMethod::kAuto:
      return "auto";
    case SparseCholeskyMethod::kSimplicial:
      return "simplicial";
    case SparseCholeskyMethod::kSupernodal:
      return "supernodal";
  }
  return "unknown";
}

const char* to_string(SparseCholeskyStatus status) {
  switch (status) {
    case SparseCholeskyStatus::kOk:
      return "ok";
    case SparseCholeskyStatus::kNotAnalysed:
      return "not analysed";
    case SparseCholeskyStatus::kNotFactorised:
      return "not factorised";
    case SparseCholeskyStatus::kInvalidInput:
      return "invalid input";
    case SparseCholeskyStatus::kPatternMismatch:
      return "pattern differs from the analysed one";
    case SparseCholeskyStatus::kNotPositiveDefinite:
      return "not positive definite";
    case SparseCholeskyStatus::kOutOfMemory:
      return "out of memory";
    case SparseCholeskyStatus::kCholmodError:
      return "CHOLMOD error";
  }
  return "unknown";
}

// A CHOLMOD workspace of its own (cholmod_solve2 allocates in it, never in the factor) and the
// dense buffers cholmod_solve2 reuses between calls (reallocated only when k changes).
struct SparseCholesky::SolveWorkspace::Impl {
  cholmod_common common;
  cholmod_dense* x = nullptr;
  cholmod_dense* y = nullptr;
  cholmod_dense* e = nullptr;

  Impl() {
    cholmod_start(&common);
    common.print = 0;
    common.error_handler = nullptr;
  }
  ~Impl() {
    if (x != nullptr) cholmod_free_dense(&x, &common);
    if (y != nullptr) cholmod_free_dense(&y, &common);
    if (e != nullptr) cholmod_free_dense(&e, &common);
    cholmod_finish(&common);
  }
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;
};

SparseCholesky::SolveWorkspace::SolveWorkspace() : impl_(std::make_unique<Impl>()) {}
SparseCholesky::SolveWorkspace::~SolveWorkspace() = default;
SparseCholesky::SolveWorkspace::SolveWorkspace(SolveWorkspace&&) noexcept = default;
SparseCholesky::SolveWorkspace& SparseCholesky::SolveWorkspace::operator=(
    SolveWorkspace&&) noexcept = default;

struct SparseCholesky::Impl {
  SparseCholeskyOptions options;
  cholmod_common common;
  cholmod_factor* factor = nullptr;
  // The solve workspace of solve() without one, kept between calls.
  SolveWorkspace workspace;
  // One per thread of solve_in_blocks().
  std::vector<SolveWorkspace> thread_workspaces;
  bool factorised = false;
  Eigen::Index n = 0;
  // The analysed pattern (compressed form), to check factorise() input.
  std::vector<int> outer;
  std::vector<int> inner;
  std::optional<Eigen::Index> minor_index;
  std::optional<Eigen::Index> failed_column;
  double analysis_seconds = 0.0;
  double factorisation_seconds = 0.0;
  double total_factorisation_seconds = 0.0;
  int num_factorisations = 0;

  explicit Impl(const SparseCholeskyOptions& o) : options(o) {
    cholmod_start(&common);
    common.print = 0;  // never print; failures are returned as statuses
    common.error_handler = nullptr;
    // Simplicial: CHOLMOD's row-oriented LLᵀ (no BLAS); supernodal: dense BLAS on supernodes.
    // kAuto analyses simplicially first and switches after looking at nnz(L) (analyse()).
    common.supernodal = options.method == SparseCholeskyMethod::kSupernodal ? CHOLMOD_SUPERNODAL
                                                                            : CHOLMOD_SIMPLICIAL;
    // LLᵀ, not LDLᵀ: the simplicial factorisation then stops at a non-positive pivot as the
    // supernodal one does (kNotPositiveDefinite), and the supernodal one is not converted after.
    common.final_ll = 1;
    switch (options.ordering) {
      case SparseCholeskyOrdering::kMetis:
        common.nmethods = 1;
        common.method[0].ordering = CHOLMOD_METIS;
        common.postorder = 1;
        break;
      case SparseCholeskyOrdering::kAmd:
        common.nmethods = 1;
        common.method[0].ordering = CHOLMOD_AMD;
        common.postorder = 1;
        break;
      case SparseCholeskyOrdering::kCholmod:
        break;  // nmethods = 0: AMD, then METIS when AMD's fill is poor
    }
  }

  ~Impl() {
    free_factor();
    cholmod_finish(&common);
  }

  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;

  void free_factor() {
    if (factor != nullptr) cholmod_free_factor(&factor, &common);
    factor = nullptr;
    factorised = false;
  }

  SparseCholeskyStatus status_from_common() const {
    if (common.status == CHOLMOD_OUT_OF_MEMORY) return SparseCholeskyStatus::kOutOfMemory;
    if (common.status == CHOLMOD_NOT_POSDEF) return SparseCholeskyStatus::kNotPositiveDefinite;
    if (common.status < CHOLMOD_OK) return SparseCholeskyStatus::kCholmodError;
    return SparseCholeskyStatus::kOk;
  }

  // A read-only CHOLMOD view of A's upper triangle (stype = 1: entries below the diagonal are
  // ignored). CHOLMOD does not modify A in analyse/factorise.
  static cholmod_sparse view(const Eigen::SparseMatrix<double>& A) {
    cholmod_sparse s{};
    s.nrow = static_cast<size_t>(A.rows());
    s.ncol = static_cast<size_t>(A.cols());
    s.nzmax = static_cast<size_t>(A.nonZeros());
    s.p = const_cast<int*>(A.outerIndexPtr());
    s.i = const_cast<int*>(A.innerIndexPtr());
    s.nz = A.isCompressed() ? nullptr : const_cast<int*>(A.innerNonZeroPtr());
    s.x = const_cast<double*>(A.valuePtr());
    s.z = nullptr;
    s.stype = 1;
    s.itype = CHOLMOD_INT;
    s.xtype = CHOLMOD_REAL;
    s.dtype = CHOLMOD_DOUBLE;
    s.sorted = 1;  // Eigen keeps inner indices sorted in each column
    s.packed = A.isCompressed() ? 1 : 0;
    return s;
  }

  bool same_pattern(const Eigen::SparseMatrix<double>& A) const {
    if (A.rows() != n || A.cols() != n || !A.isCompressed()) return false;
    if (static_cast<std::size_t>(A.nonZeros()) != inner.size()) return false;
    return std::equal(outer.begin(), outer.end(), A.outerIndexPtr()) &&
           std::equal(inner.begin(), inner.end(), A.innerIndexPtr());
  }
};

SparseCholesky::SparseCholesky(const SparseCholeskyOptions& options)
    : impl_(std::make_unique<Impl>(options)) {}
SparseCholesky::~SparseCholesky() = default;
SparseCholesky::SparseCholesky(SparseCholesky&&) noexcept = default;
SparseCholesky& SparseCholesky::operator=(SparseCholesky&&) noexcept = default;

SparseCholeskyStatus SparseCholesky::analyse(const Eigen::SparseMatrix<double>& A) {
  Impl& d = *impl_;
  d.free_factor();
  d.n = 0;
  d.outer.clear();
  d.inner.clear();
  d.minor_index.reset();
  d.failed_column.reset();
  if (A.rows() != A.cols() || A.rows() == 0) return SparseCholeskyStatus::kInvalidInput;
  // The pattern check of factorise() compares compressed arrays; require compressed input.
  if (!A.isCompressed()) return SparseCholeskyStatus::kInvalidInput;

  const auto start = Clock::now();
  cholmod_sparse a = Impl::view(A);
  d.common.supernodal = d.options.method == SparseCholeskyMethod::kSupernodal ? CHOLMOD_SUPERNODAL
                                                                              : CHOLMOD_SIMPLICIAL;
  d.factor = cholmod_analyze(&a, &d.common);
  // kAuto: a factor too large for the simplicial method's speed is analysed again supernodally
  // (the ordering is the same; nnz(L) depends on the pattern only, so every machine agrees).
  if (d.factor != nullptr && d.options.method == SparseCholeskyMethod::kAuto &&
      d.common.lnz > d.options.simplicial_max_factor_nonzeros) {
    cholmod_free_factor(&d.factor, &d.common);
    d.common.supernodal = CHOLMOD_SUPERNODAL;
    d.factor = cholmod_analyze(&a, &d.common);
  }
  d.analysis_seconds = seconds_since(start);
  if (d.factor == nullptr) {
    const SparseCholeskyStatus s = d.status_from_common();
    return s == SparseCholeskyStatus::kOk ? SparseCholeskyStatus::kCholmodError : s;
  }
  d.n = A.rows();
  d.outer.assign(A.outerIndexPtr(), A.outerIndexPtr() + A.cols() + 1);
  d.inner.assign(A.innerIndexPtr(), A.innerIndexPtr() + A.nonZeros());
  return SparseCholeskyStatus::kOk;
}

SparseCholeskyStatus SparseCholesky::factorise(const Eigen::SparseMatrix<double>& A) {
  Impl& d = *impl_;
  if (d.factor == nullptr) return SparseCholeskyStatus::kNotAnalysed;
  if (!d.same_pattern(A)) return SparseCholeskyStatus::kPatternMismatch;
  d.factorised = false;
  d.minor_index.reset();
  d.failed_column.reset();

  const auto start = Clock::now();
  cholmod_sparse a = Impl::view(A);
  const int ok = cholmod_factorize(&a, d.factor, &d.common);
  d.factorisation_seconds = seconds_since(start);
  d.total_factorisation_seconds += d.factorisation_seconds;
  ++d.num_factorisations;

  const SparseCholeskyStatus status = ok ? d.status_from_common()
                                         : (d.status_from_common() == SparseCholeskyStatus::kOk
                                                ? SparseCholeskyStatus::kCholmodError
                                                : d.status_from_common());
  if (status == SparseCholeskyStatus::kNotPositiveDefinite ||
      (status == SparseCholeskyStatus::kOk && d.factor->minor < d.factor->n)) {
    const auto m = static_cast<Eigen::Index>(d.factor->minor);
    d.minor_index = m;
    if (d.factor->Perm != nullptr && m < d.n) {
      d.failed_column = static_cast<const int*>(d.factor->Perm)[m];
    } else {
      d.failed_column = m;
    }
    return SparseCholeskyStatus::kNotPositiveDefinite;
  }
  if (status != SparseCholeskyStatus::kOk) return status;
  d.factorised = true;
  return SparseCholeskyStatus::kOk;
}

SparseCholeskyStatus SparseCholesky::compute(const Eigen::SparseMatrix<double>& A) {
  const SparseCholeskyStatus s = analyse(A);
  return s == SparseCholeskyStatus::kOk ? factorise(A) : s;
}

SparseCholeskyStatus SparseCholesky::solve(const Eigen::Ref<const Eigen::MatrixXd>& rhs,
                                           Eigen::Ref<Eigen::MatrixXd> solution) {
  return solve(rhs, solution, impl_->workspace);
}

SparseCholeskyStatus SparseCholesky::solve(const Eigen::Ref<const Eigen::MatrixXd>& rhs,
                                           Eigen::Ref<Eigen::MatrixXd> solution,
                                           SolveWorkspace& workspace) const {
  const Impl& d = *impl_;
  SolveWorkspace::Impl& w = *workspace.impl_;
  if (d.factor == nullptr) return SparseCholeskyStatus::kNotAnalysed;
  if (!d.factorised) return SparseCholeskyStatus::kNotFactorised;
  if (rhs.rows() != d.n || solution.rows() != d.n || solution.cols() != rhs.cols() ||
      rhs.cols() == 0) {
    return SparseCholeskyStatus::kInvalidInput;
  }
  cholmod_dense b{};
  b.nrow = static_cast<size_t>(rhs.rows());
  b.ncol = static_cast<size_t>(rhs.cols());
  b.d = static_cast<size_t>(rhs.outerStride());
  b.nzmax = b.d * b.ncol;
  b.x = const_cast<double*>(rhs.data());  // read only
  b.z = nullptr;
  b.xtype = CHOLMOD_REAL;
  b.dtype = CHOLMOD_DOUBLE;
  if (!cholmod_solve2(CHOLMOD_A, d.factor, &b, nullptr, &w.x, nullptr, &w.y, &w.e, &w.common)) {
    if (w.common.status == CHOLMOD_OUT_OF_MEMORY) return SparseCholeskyStatus::kOutOfMemory;
    return SparseCholeskyStatus::kCholmodError;
  }
  const Eigen::Map<const Eigen::MatrixXd, 0, Eigen::OuterStride<>> x(
      static_cast<const double*>(w.x->x), rhs.rows(), rhs.cols(),
      Eigen::OuterStride<>(static_cast<Eigen::Index>(w.x->d)));
  solution = x;
  return SparseCholeskyStatus::kOk;
}

SparseCholeskyStatus SparseCholesky::solve_in_blocks(const Eigen::Ref<const Eigen::MatrixXd>& rhs,
                                                     Eigen::Ref<Eigen::MatrixXd> solution,
                                                     Eigen::Index block_columns, int threads) {
  if (block_columns < 1 || threads < 0 || solution.cols() != rhs.cols() || rhs.cols() == 0) {
    return SparseCholeskyStatus::kInvalidInput;
  }
  if (rhs.rows() != impl_->n || solution.rows() != impl_->n) {
    return SparseCholeskyStatus::kInvalidInput;
  }
  const int used = detail::resolve_threads(threads);
  std::vector<SolveWorkspace>& workspaces = impl_->thread_workspaces;
  if (workspaces.size() < static_cast<std::size_t>(used)) {
    workspaces.resize(static_cast<std::size_t>(used));
  }
  std::vector<SparseCholeskyStatus> statuses(static_cast<std::size_t>(used),
                                             SparseCholeskyStatus::kOk);
  detail::for_each_column_block(
      rhs.cols(), block_columns, used, [&](int thread, Eigen::Index first, Eigen::Index k) {
        const auto t = static_cast<std::size_t>(thread);
        if (statuses[t] != SparseCholeskyStatus::kOk) return;
        statuses[t] = solve(rhs.middleCols(first, k), solution.middleCols(first, k), workspaces[t]);
      });
  for (const SparseCholeskyStatus status : statuses) {
    if (status != SparseCholeskyStatus::kOk) return status;
  }
  return SparseCholeskyStatus::kOk;
}

bool SparseCholesky::analysed() const {
  return impl_->factor != nullptr;
}
bool SparseCholesky::factorised() const {
  return impl_->factorised;
}
Eigen::Index SparseCholesky::rows() const {
  return impl_->n;
}
std::optional<double> SparseCholesky::factor_nonzeros() const {
  if (impl_->factor == nullptr) return std::nullopt;
  return impl_->common.lnz;
}
std::optional<Eigen::Index> SparseCholesky::factor_minor() const {
  return impl_->minor_index;
}
std::optional<Eigen::Index> SparseCholesky::failed_column() const {
  return impl_->failed_column;
}
double SparseCholesky::analysis_seconds() const {
  return impl_->analysis_seconds;
}
double SparseCholesky::factorisation_seconds() const {
  return impl_->factorisation_seconds;
}
double SparseCholesky::total_factorisation_seconds() const {
  return impl_->total_factorisation_seconds;
}
int SparseCholesky::num_factorisations() const {
  return impl_->num_factorisations;
}
std::optional<SparseCholeskyMethod> SparseCholesky::method_used() const {
  if (impl_->factor == nullptr) return std::nullopt;
  return impl_->factor->is_super ? SparseCholeskyMethod::kSupernodal
                                 : SparseCholeskyMethod::kSimplicial;
}
std::optional<std::string> SparseCholesky::ordering_used() const {
  if (impl_->factor == nullptr) return std::nullopt;
  return std::string(cholmod_ordering_name(impl_->factor->ordering));
}

}  // namespace sinew::offline
