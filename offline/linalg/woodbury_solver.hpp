#pragma once
/// The Gauss–Newton system of seed 003 (§3.4, eqs. 11–14) and its two solvers:
///   H y = h,   H = L² + ZᵀZ   (6m x 6m, dense: never formed),
/// with L the plastic-strain Laplacian (offline/plastic/plastic_strain_laplacian.hpp) and Z (r x
/// 6m, dense, r = 3·#constraints) the constraint rows times the equilibrium Jacobian (eq. 12).
///
/// Woodbury (eqs. 13–14): H = B + ẐᵀẐ with B = L² − Σψᵢψᵢᵀ and Ẑ = [Z; Ψᵀ] (Ψ = the six nullspace
/// vectors of L as columns), so that
///   y = B⁻¹h − B⁻¹Ẑᵀ (I + ẐB⁻¹Ẑᵀ)⁻¹ ẐB⁻¹h.
/// B is never formed either (ψψᵀ is dense). On the range of L, B = L²; on its nullspace, B = −I. So
///   B⁻¹ = (L²)⁺ − ΨΨᵀ,   (L²)⁺ = (L^sc⁺)² ⊗ diag(1/w²)
/// (L = L^sc ⊗ diag(w), tet-major). L^sc⁺ is applied exactly with one sparse Cholesky factor of the
/// grounded scalar Laplacian (row and column of tet 0 removed: SPD on a connected mesh) followed by
/// projection onto 1⊥: "B factorised once per run", and m x m instead of 6m x 6m. The capacitance
/// matrix I + ẐB⁻¹Ẑᵀ ((r+6) x (r+6), symmetric indefinite: its last 6x6 block is 0) is
/// LU-factorised.
///
/// Conjugate gradients on H (matrix-free, H v = L(Lv) + Zᵀ(Zv)) is the reference the paper compares
/// with (Table 1); it is here for tests and benchmarks.
#include <Eigen/Core>
#include <Eigen/LU>
#include <Eigen/SparseCore>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "offline/linalg/sparse_cholesky.hpp"
#include "offline/plastic/plastic_strain_laplacian.hpp"

namespace sinew::offline {

struct WoodburySolverOptions {
  /// Ordering of the Cholesky factorisation of the grounded scalar Laplacian.
  SparseCholeskyOrdering ordering = SparseCholeskyOrdering::kMetis;
  /// Its numeric method (see SparseCholeskyMethod); kAuto: simplicial (the same bits on every
  /// CPU) up to 1e6 nonzeros in the factor, supernodal above.
  SparseCholeskyMethod cholesky_method = SparseCholeskyMethod::kAuto;
  /// Right-hand sides of B⁻¹ handled per block solve (each becomes 6 columns of L^sc solves):
  /// bounds the work memory to about 12·m·block_columns doubles per thread; ≥ 1. CHOLMOD's
  /// supernodal solve is fastest per column at 48–192 columns on this machine (0.79 ms per column
  /// at m = 30k for 48, 1.3 for 768, 2.6 for 3,072: larger blocks leave the cache).
  int block_columns = 16;
  /// Threads of the Laplacian block solves, each with its own blocks and CHOLMOD workspace;
  /// 0 = the CPUs this process may use (detail::available_threads); ≥ 0.
  int threads = 0;
  /// Back the r·6m work matrix L⁺Zᵀ with transparent huge pages (detail/huge_pages.hpp).
  bool huge_pages = true;
  /// Steps of iterative refinement after the Woodbury solve: y += H⁻¹(h − Hy) with the same
  /// factorisations (one product with H and one cheap solve each). At 30k tets and 900 rows the
  /// plain solve leaves ‖h − Hy‖/‖h‖ = 8e-8 (the capacitance matrix loses digits); ≥ 0.
  int refinement_steps = 1;
  /// Empty when valid; otherwise one line naming the field, its value and the constraint.
  std::optional<std::string> validate() const;
};

enum class WoodburyStatus {
  kOk,
  kInvalidOptions,       ///< WoodburySolverOptions::validate() failed
  kDisconnectedMesh,     ///< the tet adjacency has ≠ 1 component: L's nullspace is larger than Ψ
  kInvalidInput,         ///< sizes do not match, NaN / infinity, or no mesh
  kFactorisationFailed,  ///< CHOLMOD could not factorise the grounded Laplacian
  kSingularCapacitance,  ///< I + ẐB⁻¹Ẑᵀ is singular: H is (numerically) singular
  kNotFactorised,        ///< solve() before a successful set_constraint_rows_transposed()
};
const char* to_string(WoodburyStatus status);

/// Solves H y = h by eq. 14. create() factorises the grounded scalar Laplacian once;
/// set_constraint_rows_transposed(Zᵀ) forms the capacitance from Y = L⁺Zᵀ (one Laplacian solve per
/// row of Z, since (L²)⁺ = L⁺L⁺) as I + YᵀY − … and LU-factorises it; solve(h) is then four
/// single-column Laplacian solves, two thin products with Z and one small LU solve.
class WoodburySolver {
 public:
  /// adjacency: face adjacency of the m tets (tet_face_adjacency); it must be ok() and connected.
  static std::optional<WoodburySolver> create(const TetAdjacency& adjacency, Eigen::Index num_tets,
                                              const WoodburySolverOptions& options = {},
                                              std::string* error = nullptr);

  Eigen::Index num_tets() const { return num_tets_; }
  Eigen::Index size() const { return 6 * num_tets_; }  ///< 6m

  /// out = B⁻¹ V for the columns of V (6m x k, tet-major); out must be 6m x k and not alias V.
  WoodburyStatus apply_base_inverse(const Eigen::Ref<const Eigen::MatrixXd>& V,
                                    Eigen::Ref<Eigen::MatrixXd> out);
  /// out = (L²)⁺ V (the pseudo-inverse of L², exact); same shapes as apply_base_inverse.
  WoodburyStatus apply_squared_laplacian_pseudo_inverse(const Eigen::Ref<const Eigen::MatrixXd>& V,
                                                        Eigen::Ref<Eigen::MatrixXd> out);

  /// Prepares the solve for H = L² + ZᵀZ + δΨΨᵀ, given Zᵀ (6m x r: the constraint rows as
  /// columns, the layout constraint_jacobian produces; taken by value, pass it with std::move to
  /// avoid a copy of what is 1.3 GB at 30k tets and 900 rows). δ ≥ 0 damps only the six
  /// constant-strain modes (Ψ, the nullspace of L), where H is singular when the constraints do not
  /// see a uniform change of s (e.g. stiff attachments alone):
  ///   δ = relative·‖ZΨ‖²_F/6 + floor·‖Z‖²_F/6 + 1e-12,
  /// relative to the constraints' own curvature along Ψ, with a floor relative to their total
  /// curvature (so a mode the constraints do not see at all is still damped at their scale). It
  /// enters as Ẑ's last six rows √(1 + δ)·Ψᵀ, so B is unchanged.
  WoodburyStatus set_constraint_rows_transposed(Eigen::MatrixXd Zt, double relative = 0.0,
                                                double floor = 0.0);
  /// The same solve with the tets `held` held: their six entries of y are 0, and y solves the
  /// rows of H y = h of the other (free) tets F, i.e. the limit of six penalty rows ∞·eᵢᵀ per
  /// held tet (GaussNewtonOptions::hold_clamped_tets). Without any extra row: B becomes
  ///   B_F = [(L^sc)²]_FF ⊗ diag(w²)
  /// (SPD once a tet is held on a connected mesh), factorised by one sparse Cholesky of the
  /// m_F x m_F matrix [(L^sc)²]_FF per call, V = B_F⁻¹Zᵀ is kept in the memory L⁺Zᵀ takes, and the
  /// capacitance is I + ẐV with Ẑ = [Z; √δ Ψᵀ] restricted to F ((r+6) x (r+6), SPD). Memory is that
  /// of the unheld solve whatever the number of held tets (penalty rows cost 2·8·6m bytes per row
  /// in Zᵀ and L⁺Zᵀ and grow the capacitance). δ is the one the penalty rows penalty·eᵢᵀ would
  /// give (they add 6·#held·penalty²/m to ‖ZΨ‖²_F and 6·#held·penalty² to ‖Z‖²_F), so that this
  /// solve is the limit of set_constraint_rows_transposed() with those rows as penalty → ∞ at a
  /// fixed δ. Every tet held, or an index out of range: kInvalidInput. An empty `held` is
  /// set_constraint_rows_transposed().
  WoodburyStatus set_constraint_rows_transposed_holding(Eigen::MatrixXd Zt,
                                                        const std::vector<Eigen::Index>& held,
                                                        double relative = 0.0, double floor = 0.0,
                                                        double penalty = 0.0);
  /// Tets held by the last set_constraint_rows_transposed_holding() (0 after the plain one).
  Eigen::Index held_tets() const { return held_count_; }
  /// Columns of the Zᵀ kept (r) and rows of the dense capacitance (r + 6) of the last call: what
  /// the memory grows with (2·8·6m·r bytes for Zᵀ and L⁺Zᵀ, 8·(r + 6)² for the capacitance).
  Eigen::Index constraint_rows() const { return Zt_.cols(); }
  Eigen::Index capacitance_size() const { return capacitance_.rows(); }
  /// Hands back the Zᵀ of the last set_constraint_rows_transposed() (solve() is refused until the
  /// next one), so that the next Z can be written into the same memory: fresh pages of a
  /// gigabyte-sized matrix cost seconds to fault in and zero on this machine.
  Eigen::MatrixXd release_constraint_rows();
  /// δ of the last set_constraint_rows_transposed().
  double nullspace_damping() const { return nullspace_scale_ * nullspace_scale_ - 1.0; }
  /// y = H⁻¹ h (6m); y must be 6m and not alias h.
  WoodburyStatus solve(const Eigen::Ref<const Eigen::VectorXd>& h, Eigen::Ref<Eigen::VectorXd> y);

  /// Seconds of the last set_constraint_rows_transposed(): Y = L⁺Zᵀ (Laplacian solves) and the
  /// capacitance (the product YᵀY and the LU).
  double base_solve_seconds() const { return base_solve_seconds_; }
  double capacitance_seconds() const { return capacitance_seconds_; }
  /// Seconds of the one-off factorisation in create().
  double factorisation_seconds() const { return factorisation_seconds_; }

 private:
  WoodburySolver() = default;
  // One thread's CHOLMOD workspace and m x 6k gather / solution blocks, kept between calls.
  struct ThreadWork {
    SparseCholesky::SolveWorkspace cholmod;
    Eigen::MatrixXd rhs, solution;
  };
  // Gathers columns [first, first + k) of V (6m, tet-major) into work.rhs (m x 6k: one column per
  // component), applies L^sc⁺ `times` times, scatters with 1/w^times into out's columns
  // [first, first + k). Different threads may run it on disjoint column ranges.
  void component_pseudo_inverse(const Eigen::Ref<const Eigen::MatrixXd>& V, Eigen::Index first,
                                Eigen::Index k, int times, ThreadWork& work,
                                Eigen::Ref<Eigen::MatrixXd> out) const;
  // out = B_F⁻¹ V for columns [first, first + k) of V (held mode), zero on the held tets.
  void held_base_inverse(const Eigen::Ref<const Eigen::MatrixXd>& V, Eigen::Index first,
                         Eigen::Index k, ThreadWork& work, Eigen::Ref<Eigen::MatrixXd> out) const;
  void held_base_inverse_of_columns(const Eigen::Ref<const Eigen::MatrixXd>& V,
                                    Eigen::Ref<Eigen::MatrixXd> out);
  WoodburyStatus held_solve_once(const Eigen::Ref<const Eigen::VectorXd>& h,
                                 Eigen::Ref<Eigen::VectorXd> y);
  // One Woodbury solve (eq. 14) without refinement.
  WoodburyStatus solve_once(const Eigen::Ref<const Eigen::VectorXd>& h,
                            Eigen::Ref<Eigen::VectorXd> y);
  // Z_psi_ = ZΨ from Zt_.
  void compute_z_psi();
  // out = H v = L²v + ZᵀZv + δΨΨᵀv.
  void apply_hessian(const Eigen::VectorXd& v, Eigen::VectorXd& out) const;
  // In place: columns of U (m x k) ← L^sc⁺ U.
  void scalar_pseudo_inverse(Eigen::MatrixXd& U, ThreadWork& work) const;
  // out = L⁺^times V, column blocks over the threads.
  void component_pseudo_inverse_of_columns(const Eigen::Ref<const Eigen::MatrixXd>& V, int times,
                                           Eigen::Ref<Eigen::MatrixXd> out);

  WoodburySolverOptions options_;
  Eigen::Index num_tets_ = 0;
  SparseCholesky grounded_;                       // L^sc without row/column 0
  Eigen::SparseMatrix<double> scalar_laplacian_;  // L^sc (m x m), for the refinement's H v
  Eigen::MatrixXd Zt_;            // 6m x r: Zᵀ of the last set_constraint_rows_transposed()
  Eigen::MatrixXd Y_;             // 6m x r: L⁺Zᵀ, kept for its memory (see above)
  Eigen::MatrixXd Z_psi_;         // r x 6: ZΨ
  double nullspace_scale_ = 1.0;  // √(1 + δ)
  Eigen::PartialPivLU<Eigen::MatrixXd> capacitance_;
  bool factorised_ = false;
  // Held mode (set_constraint_rows_transposed_holding): free_index_[t] = t's row in B_F's
  // scalar factor, −1 when held; Y_ then holds V = B_F⁻¹Zᵀ and psi_solved_ = B_F⁻¹(√δ Ψ).
  Eigen::Index held_count_ = 0;
  std::vector<Eigen::Index> free_index_;
  Eigen::Index num_free_ = 0;
  SparseCholesky held_factor_;
  Eigen::MatrixXd psi_solved_;  // 6m x 6
  std::vector<ThreadWork> held_work_;
  int threads_ = 1;
  std::vector<ThreadWork> work_;  // one per thread
  double base_solve_seconds_ = 0.0;
  double capacitance_seconds_ = 0.0;
  double factorisation_seconds_ = 0.0;
};

/// H v = L(Lv) + Zᵀ(Zv) into out (6m). L: the 6m x 6m plastic-strain Laplacian; Zt: Zᵀ, 6m x r.
void apply_gauss_newton_hessian(const Eigen::SparseMatrix<double>& L,
                                const Eigen::Ref<const Eigen::MatrixXd>& Zt,
                                const Eigen::Ref<const Eigen::VectorXd>& v,
                                Eigen::Ref<Eigen::VectorXd> out);

struct ConjugateGradientOptions {
  int max_iterations = 100000;        ///< ≥ 1
  double relative_tolerance = 1e-10;  ///< stop when ‖h − Hy‖ ≤ tol·‖h‖; in (0, 1)
  /// Stop after this much wall-clock time (seconds; 0 = no limit, ≥ 0): the benchmark's cap.
  double max_seconds = 0.0;
  /// Called every progress_every iterations with the iterate y and the recursive relative
  /// residual; returning false stops the solve (a benchmark stops once y matches a reference).
  std::function<bool(int iteration, const Eigen::VectorXd& y, double relative_residual)> progress;
  int progress_every = 500;  ///< ≥ 1
  std::optional<std::string> validate() const;
};

struct ConjugateGradientSummary {
  bool converged = false;
  int iterations = 0;
  double relative_residual = 0.0;  ///< ‖h − Hy‖ / ‖h‖ at the end
  double seconds = 0.0;
};

/// Unpreconditioned conjugate gradients on H y = h (Table 1's CG), from y = 0. Zt: Zᵀ, 6m x r.
ConjugateGradientSummary conjugate_gradient_solve(const Eigen::SparseMatrix<double>& L,
                                                  const Eigen::Ref<const Eigen::MatrixXd>& Zt,
                                                  const Eigen::Ref<const Eigen::VectorXd>& h,
                                                  Eigen::Ref<Eigen::VectorXd> y,
                                                  const ConjugateGradientOptions& options = {});

}  // namespace sinew::offline
