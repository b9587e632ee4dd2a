#pragma once
/// Static equilibrium under plastic strain (seed 003, eq. 4 / eq. 7):
///   f_net(s, x) = f_e(Fp(s), x) + f_a(x) = 0
/// for a given plastic state s (6m). f_e = ∂E/∂x and f_a = ∂E_a/∂x (appendix F, eq. 56) are
/// gradients, so the equilibrium is a stationary point of the total potential
///   Π(x) = E(s, x) + E_a(x),
/// and the solver MINIMISES Π from a start x0 (a warm start: the Gauss–Newton line search of §3.4
/// solves for x(η) from the previous equilibrium, and an equilibrium that fails scores +∞ there).
///
/// Two back ends (EquilibriumMethod):
///  - kNewton: K_total = K + H_a (K = ∂²E/∂x², per-element PSD projection when needed; H_a =
///    Σ c_k A_kᵀA_k) factorised with CHOLMOD (symbolic analysis once at create(), numeric per
///    iteration), backtracking Armijo line search on Π; a trial step that inverts a tet that was
///    not inverted at x0, or makes Π non-finite, is shortened.
///  - kIpopt: an unconstrained NLP (the paper used Knitro's interior point) with the exact sparse
///    gradient and the Hessian as the lower-triangle COO of K_total (pattern fixed at create()).
///
/// Convergence (both back ends): ‖f_net‖∞ ≤ force_tolerance · force_scale, where
///   force_scale = max(μ·h², ‖f_e‖∞, ‖f_a‖∞),  h = (mean rest tet volume)^(1/3),
/// i.e. a nodal force residual measured against the elastic force of a unit strain on a typical
/// element face, or against the largest force in play when attachments pull harder than that (so
/// that round-off in the cancellation f_e + f_a cannot stall a stiff-spring solve).
///
/// Free objects (an empty attachment set, §3.6): Π is invariant under rigid motions and K_total is
/// singular along them; the Newton back end then holds six dofs of the start x fixed
/// (offline/rigid/rigid_motion.hpp) and returns one equilibrium of the six-dimensional family,
/// which the caller moves to its rigid frame (offline/rigid/rigid_stabilisation.hpp). kIpopt is
/// refused there.
///
/// Ipopt's and CHOLMOD's headers stay in equilibrium.cpp / sparse_cholesky.cpp.

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <array>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "common/material/stable_neo_hookean.hpp"
#include "offline/constraints/constraints.hpp"
#include "offline/linalg/sparse_cholesky.hpp"
#include "offline/plastic/plastic_elastic_energy.hpp"

namespace sinew::offline {

enum class EquilibriumMethod {
  kNewton,  ///< Newton + CHOLMOD + backtracking line search
  kIpopt,   ///< Ipopt (interior point; here unconstrained) with exact sparse Hessian
};

const char* to_string(EquilibriumMethod method);

/// Which stiffness the Newton back end factorises (Ipopt: kAlways uses the projected K as its
/// "Hessian", anything else the exact K; Ipopt corrects the inertia itself).
enum class StiffnessProjection {
  kNever,  ///< exact K: quadratic convergence, fails (kNotPositiveDefinite) if K_total is not PD
  kOnFailure,  ///< exact K; re-assembled with the per-element PSD projection for any iteration
               ///< whose exact K_total is not positive definite
  kAlways,     ///< always the projected K: robust far from equilibrium, only linear convergence
               ///< where the exact K is indefinite
};

const char* to_string(StiffnessProjection projection);

/// Ipopt's derivative checker (finite differences at x0); for tests, never in production solves.
enum class IpoptDerivativeTest {
  kNone,
  kFirstOrder,   ///< gradient only
  kSecondOrder,  ///< gradient and Hessian
};

struct EquilibriumOptions {
  EquilibriumMethod method = EquilibriumMethod::kNewton;
  /// Newton iterations (Ipopt: max_iter); ≥ 0. 0 only evaluates the residual at x0.
  int max_iterations = 100;
  /// Convergence when ‖f_net‖∞ ≤ force_tolerance·force_scale (see the header comment);
  /// dimensionless, in (0, 1). 1e-8 is a strain-like error of 1e-8 per element.
  double force_tolerance = 1e-8;

  /// Newton: which stiffness to factorise.
  StiffnessProjection stiffness_projection = StiffnessProjection::kOnFailure;
  /// The projection used when projecting; kProjectElement (clamp the 12x12 element Hessian) or
  /// kProjectDPdF (clamp the 9x9 ∂P/∂F: cheaper, a little more conservative). Not kNone.
  common::HessianProjection projection = common::HessianProjection::kProjectElement;
  /// Armijo sufficient-decrease parameter c₁ of Π(x + αΔx) ≤ Π(x) + c₁α∇Πᵀ Δx; in (0, 0.5).
  double armijo_parameter = 1e-4;
  /// Step shrink factor per backtracking step (also for inverting / non-finite trials); in (0, 1).
  double backtracking_factor = 0.5;
  /// Backtracking steps per Newton iteration before kLineSearchFailed; ≥ 1.
  int max_line_search_steps = 40;
  /// Reject trial steps that invert a tet that was not inverted at x0 (stable neo-Hookean is
  /// finite for inverted tets, so the energy alone does not stop inversion).
  bool reject_inversions = true;
  /// Fill-reducing ordering of the CHOLMOD analysis.
  SparseCholeskyOrdering ordering = SparseCholeskyOrdering::kMetis;
  /// Numeric method of the Newton factorisations (and of the Gauss–Newton tangent, which is
  /// the same matrix): simplicial (no BLAS, the same bits on every CPU), supernodal (faster on
  /// large meshes, rounding that depends on the CPU's OpenBLAS kernels), or kAuto (simplicial up
  /// to 1e6 nonzeros in the factor); see SparseCholeskyMethod.
  SparseCholeskyMethod cholesky_method = SparseCholeskyMethod::kAuto;

  /// Ipopt's print_level, in [0, 12]; 0 is silent (the banner is suppressed too).
  int ipopt_print_level = 0;
  /// Ipopt's derivative checker at x0 (tests only); its error count goes to the summary.
  IpoptDerivativeTest ipopt_derivative_test = IpoptDerivativeTest::kNone;
  /// Relative tolerance of the derivative checker; in (0, 1).
  double ipopt_derivative_test_tolerance = 1e-4;
  /// Relative finite-difference perturbation of the derivative checker; in (0, 0.1).
  double ipopt_derivative_test_perturbation = 1e-8;

  /// Empty when valid; otherwise one line naming the field, its value and the constraint.
  std::optional<std::string> validate() const;
};

enum class EquilibriumStatus {
  kConverged,            ///< ‖f_net‖∞ ≤ force_tolerance·force_scale
  kMaxIterations,        ///< iteration limit reached first
  kLineSearchFailed,     ///< no acceptable step along the Newton direction
  kNotPositiveDefinite,  ///< K_total not positive definite (and no projection allowed / helped)
  kIpoptFailed,          ///< Ipopt stopped without meeting the tolerance (see ipopt_return_code)
  kNonFinite,            ///< NaN / infinity in s, x0, or in Π or f_net at x0; or a singular Fp
  kInvalidInput,         ///< s is not 6m or x is not 3n
};

const char* to_string(EquilibriumStatus status);

struct EquilibriumSummary {
  EquilibriumStatus status = EquilibriumStatus::kInvalidInput;
  EquilibriumMethod method = EquilibriumMethod::kNewton;
  /// Newton iterations taken (Ipopt: its iteration count).
  int iterations = 0;
  /// ‖f_net‖∞ at the returned x (newtons); std::nullopt when it could not be evaluated.
  std::optional<double> residual_norm;
  /// ‖f_net‖∞ at x0 (newtons); std::nullopt when it could not be evaluated.
  std::optional<double> initial_residual_norm;
  /// force_scale at the returned x (newtons), the denominator of the convergence test.
  double force_scale = 0.0;
  /// Π = E + E_a at the returned x (joules); std::nullopt when it could not be evaluated.
  std::optional<double> energy;
  int factorisations = 0;            ///< numeric CHOLMOD factorisations (Newton)
  int projected_factorisations = 0;  ///< of which with the projected stiffness
  int energy_evaluations = 0;        ///< evaluations of Π (line search trials included)
  int rejected_inversions = 0;       ///< trial steps shortened because they inverted a tet
  /// Ipopt's ApplicationReturnStatus (kIpopt only), as its integer code.
  std::optional<int> ipopt_return_code;
  /// Errors reported by Ipopt's derivative checker (when it was requested and ran).
  std::optional<int> derivative_test_errors;
  double seconds = 0.0;                ///< wall-clock time of solve()
  double factorisation_seconds = 0.0;  ///< of which CHOLMOD numeric factorisations
  double assembly_seconds = 0.0;       ///< of which evaluations of E, f_e, K (and Π trials)

  bool converged() const { return status == EquilibriumStatus::kConverged; }
  /// One line: status, iterations, residual, time.
  std::string brief_report() const;
  /// Several lines: every field.
  std::string full_report() const;
};

namespace detail {
class EquilibriumIpoptProblem;
}

/// Solves the static equilibrium for given plastic strains. create() builds the solver's own
/// plastic elastic energy instances (exact and, if needed, projected; upper-triangle storage) from
/// the mesh and material of the given energy, merges their stiffness pattern with the constraint
/// Hessian's into K_total and analyses it once with CHOLMOD. Every constraint of `attachments`
/// acts as a spring in f_net (pass the attachments only, §3.3); the solver keeps a pointer to it,
/// so it must outlive the solver and may change its targets and weights between solves (the
/// pattern of its Hessian is fixed). Movable, not copyable.
class EquilibriumSolver {
 public:
  /// std::nullopt when the options are invalid, the energy cannot be rebuilt, or the sizes of the
  /// energy and the attachments differ; error (if not null) then says why.
  static std::optional<EquilibriumSolver> create(const PlasticElasticEnergy& energy,
                                                 const PointConstraints& attachments,
                                                 const EquilibriumOptions& options = {},
                                                 std::string* error = nullptr);

  EquilibriumSolver(EquilibriumSolver&&) noexcept;
  EquilibriumSolver& operator=(EquilibriumSolver&&) noexcept;
  EquilibriumSolver(const EquilibriumSolver&) = delete;
  EquilibriumSolver& operator=(const EquilibriumSolver&) = delete;
  ~EquilibriumSolver();

  const EquilibriumOptions& options() const { return options_; }
  Eigen::Index num_dofs() const { return num_dofs_; }
  /// μ·h² (newtons): the x-independent part of force_scale.
  double elastic_force_scale() const { return elastic_force_scale_; }
  /// Number of stored entries (upper triangle) of K_total.
  Eigen::Index hessian_nonzeros() const { return total_.nonZeros(); }
  /// Nonzeros of CHOLMOD's factor of K_total (std::nullopt if the analysis failed).
  std::optional<double> factor_nonzeros() const { return cholesky_.factor_nonzeros(); }

  /// Minimises Π(x) = E(s, x) + E_a(x) from the start in x (3n, metres) for the plastic state s
  /// (6m). On return x holds the last accepted iterate (the equilibrium when converged; Π never
  /// increases from x0); for kInvalidInput and kNonFinite detected at x0 it is unchanged. Never
  /// throws, never prints (except Ipopt with ipopt_print_level > 0).
  EquilibriumSummary solve(const Eigen::Ref<const Eigen::VectorXd>& s,
                           Eigen::Ref<Eigen::VectorXd> x);

  /// f_net = f_e + f_a at (s, x) into net_force (3n); false when it cannot be evaluated (sizes,
  /// non-finite values, singular Fp).
  bool net_force(const Eigen::Ref<const Eigen::VectorXd>& s,
                 const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::VectorXd> net_force);

 private:
  friend class detail::EquilibriumIpoptProblem;

  EquilibriumSolver(const EquilibriumOptions& options, const PointConstraints& attachments,
                    PlasticElasticEnergy exact);

  // Π at x, or std::nullopt when not finite / not evaluable / (with reject_inversions) when x
  // inverts a tet not inverted at the start (inversion_rejected is then set).
  std::optional<double> total_energy(const Eigen::Ref<const Eigen::VectorXd>& s,
                                     const Eigen::Ref<const Eigen::VectorXd>& x,
                                     bool* inversion_rejected = nullptr);
  // Π and ∇Π = f_net into gradient_; false when not evaluable or not finite.
  bool energy_and_gradient(const Eigen::Ref<const Eigen::VectorXd>& s,
                           const Eigen::Ref<const Eigen::VectorXd>& x, double* energy);
  // K_total at x into total_ (exact or projected stiffness); false when not evaluable.
  bool assemble_total_stiffness(const Eigen::Ref<const Eigen::VectorXd>& s,
                                const Eigen::Ref<const Eigen::VectorXd>& x, bool projected);
  // Marks the tets inverted at x (relative to their rest orientation) in inverted_at_start_.
  void record_inversions(const Eigen::Ref<const Eigen::VectorXd>& x);
  bool inverts_new_tet(const Eigen::Ref<const Eigen::VectorXd>& x) const;

  EquilibriumSummary solve_newton(const Eigen::Ref<const Eigen::VectorXd>& s,
                                  Eigen::Ref<Eigen::VectorXd> x, EquilibriumSummary summary);
  EquilibriumSummary solve_ipopt(const Eigen::Ref<const Eigen::VectorXd>& s,
                                 Eigen::Ref<Eigen::VectorXd> x, EquilibriumSummary summary);

  EquilibriumOptions options_;
  const PointConstraints* attachments_ = nullptr;
  Eigen::Index num_dofs_ = 0;
  double elastic_force_scale_ = 0.0;
  PlasticElasticEnergy exact_;
  std::optional<PlasticElasticEnergy> projected_;
  // K_total = K + H_a, upper triangle; values rebuilt through the two scatter maps (pairs of
  // source value index → total value index).
  Eigen::SparseMatrix<double> total_;
  std::vector<std::pair<int, int>> stiffness_map_;
  std::vector<std::pair<int, int>> attachment_map_;
  SparseCholesky cholesky_;
  std::vector<char> inverted_at_start_;  // per tet
  // Work vectors (3n).
  Eigen::VectorXd gradient_;
  Eigen::VectorXd attachment_gradient_;
  Eigen::VectorXd step_;
  Eigen::VectorXd trial_;
  // Running counters of the current solve.
  int energy_evaluations_ = 0;
  int rejected_inversions_ = 0;
  double assembly_seconds_ = 0.0;
  double last_force_scale_ = 0.0;
  // Free object (no attachments): six pinned dofs per Newton solve, chosen from its start x.
  bool free_object_ = false;
  std::optional<std::array<Eigen::Index, 6>> pins_;
};

}  // namespace sinew::offline
