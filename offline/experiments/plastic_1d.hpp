#pragma once
/// Seed 003 §4.5 / Fig. 23: the 1D comparison of plastic-strain registration with variational
/// shape modelling (eq. 25). A bar with rest shape [0, 1] is split into N equal elements; element
/// e has a plastic stretch p_e (the 1D F_p, piecewise constant) and the nodes carry x.
///
/// Two plastic models (Plastic1DModel):
///  - kPaperQuadratic, eqs. 26–27 verbatim: the elastic energy is E(x, p) = ∫ (ẋ/f_p − 1)², the
///    attachments x(0) = 0, x(1) = 2 are hard, and the equilibrium (eq. 27) is explicit:
///    ẋ = f_p (1 + c f_p) with c = (2 − ∫f_p) / ∫f_p² (PaperQuadraticBar1D). The registration is
///      min_p  S(p) + α Σ_l (x_l(p) − y_l)² + β E(x(p), p)                               (eq. 26)
///    solved by Levenberg–Marquardt (Gauss–Newton of §3.4 plus damping) with the exact Jacobian.
///  - kStableNeoHookean: E_e = V(s_e) ψ(F_e / s_e), V = s_e h, ψ the 1D stable neo-Hookean energy
///    [Smith et al. 2018] (I_C = f², J = f),
///      ψ(f) = μ/2 (f² − 1) − μ/2 ln((f² + 1)/2) + λ/2 (f − a)² − λ/2 (1 − a)²,  a = 1 + μ/(2λ),
///    stiff attachment springs E_a = Σ k/2 (x_a − t_a)² (appendix F), Newton equilibrium, and the
///    registration min_s S(s) + α Σ_l (x_l − y_l)² + β E_a(x) with J = −K⁻¹ ∂f/∂s (eqs. 3–10).
/// S is the smoothness (Smoothness1DOrder): first order ∫ ḟ_p² = Σ (p_{e+1} − p_e)² / h (eq. 26),
/// or second order ‖L p‖² with L the combinatorial element Laplacian (eq. 3, appendix A).
///
/// Findings (N = 200, β = 1, kPaperQuadratic, first order; see Fig23Metrics and
/// fig23_table): once the landmarks are met (α ≥ 1e4) the result no longer depends on α, hardly on
/// β ≤ 1 and not on N: x is monotone in [0, 2], but ẋ is smooth, so the least-squares slopes over
/// the subinterval interiors are ≈ 0.83 / 5.52 / 0.76, not 1 / 5 / 1 within 5%. β → ∞ forces
/// c → 0, ẋ = f_p, and eq. 26 becomes the r = 2 variational problem (with its wiggles).
/// The variational baselines (eq. 25) are solve_variational_1d: r = 1 is the piecewise-linear
/// interpolant (exactly 1 / 5 / 1 as α → ∞), r = 2, 3 overshoot and are non-monotone.
/// Dense Eigen algebra: N is small.

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

namespace sinew::offline::experiments {

/// The 1D stable neo-Hookean density ψ(f) and its first two derivatives (dimensionless f).
struct Psi1D {
  double mu = 1.0;      ///< shear-like modulus μ (Pa), > 0
  double lambda = 1.0;  ///< bulk-like modulus λ (Pa), > 0
  double value(double f) const;
  double first(double f) const;
  double second(double f) const;
};

/// The Fig. 23 setup: point constraints on material points X (rest coordinate in [0, 1]).
struct Plastic1DSetup {
  std::vector<double> attachment_X{0.0, 1.0};       ///< attached material points
  std::vector<double> attachment_target{0.0, 2.0};  ///< their world positions
  std::vector<double> landmark_X{0.25, 0.5};        ///< landmark material points
  std::vector<double> landmark_target{0.25, 1.5};   ///< their world positions
};

/// The discrete bar: nodes X_i = i h, i = 0..N, and its energies. Constraint points are snapped to
/// the nearest node (N a multiple of 4 makes Fig. 23's points exact).
class PlasticBar1D {
 public:
  PlasticBar1D(int num_elements, Psi1D psi, double attachment_stiffness, Plastic1DSetup setup);

  int num_elements() const { return n_; }
  double h() const { return 1.0 / n_; }
  const Plastic1DSetup& setup() const { return setup_; }
  const std::vector<int>& attachment_nodes() const { return attachment_nodes_; }
  const std::vector<int>& landmark_nodes() const { return landmark_nodes_; }

  /// Π(x, s) = Σ_e E_e(x, s) + E_a(x) (J per unit cross-section); x is N+1, s is N.
  double energy(const Eigen::VectorXd& x, const Eigen::VectorXd& s) const;
  /// ∂Π/∂x (N+1): minus the net nodal force.
  Eigen::VectorXd gradient_x(const Eigen::VectorXd& x, const Eigen::VectorXd& s) const;
  /// ∂Π/∂s (N).
  Eigen::VectorXd gradient_s(const Eigen::VectorXd& x, const Eigen::VectorXd& s) const;
  /// K = ∂²Π/∂x² (N+1 x N+1, tridiagonal plus the spring diagonal): the tangent stiffness.
  Eigen::MatrixXd hessian_xx(const Eigen::VectorXd& x, const Eigen::VectorXd& s) const;
  /// ∂²Π/∂x∂s (N+1 x N): the mixed derivative driving J = −K⁻¹ ∂²Π/∂x∂s.
  Eigen::MatrixXd hessian_xs(const Eigen::VectorXd& x, const Eigen::VectorXd& s) const;
  /// ∂²Π/∂s² (N x N, diagonal).
  Eigen::MatrixXd hessian_ss(const Eigen::VectorXd& x, const Eigen::VectorXd& s) const;
  /// E_a(x) = Σ_a k/2 (x_a − t_a)².
  double attachment_energy(const Eigen::VectorXd& x) const;
  /// The combinatorial element Laplacian L (N x N): (L s)_e = Σ_{n ~ e} (s_n − s_e).
  Eigen::MatrixXd plastic_strain_laplacian() const;

 private:
  int n_;
  Psi1D psi_;
  double k_;
  Plastic1DSetup setup_;
  std::vector<int> attachment_nodes_, landmark_nodes_;
};

/// The smoothness term S(p) of the registration.
enum class Smoothness1DOrder {
  kFirst,   ///< ∫ ḟ_p² dt = Σ_e (p_{e+1} − p_e)² / h: eq. 26
  kSecond,  ///< ‖L p‖², L = PlasticBar1D::plastic_strain_laplacian(): the 3D eq. 3 in 1D
};
const char* to_string(Smoothness1DOrder order);

/// The matrix W of S(p) = ‖W p‖² (N−1 x N for kFirst, N x N for kSecond).
Eigen::MatrixXd smoothness_matrix(int num_elements, Smoothness1DOrder order);

/// Eqs. 26–27 on the discrete bar: element e has plastic stretch p_e ≠ 0, the elastic energy is
/// E(x, p) = Σ_e h (d_e / (h p_e) − 1)², d_e = x_{e+1} − x_e (the quadrature of ∫ (ẋ/f_p − 1)²),
/// and the two attachments are hard at the end nodes. Its minimiser over x (eq. 27) is explicit:
///   d_e = h p_e (1 + c p_e),  c = (T − S₁) / S₂,  S₁ = h Σ p_e,  S₂ = h Σ p_e²,  T = t₁ − t₀,
/// so E(x(p), p) = c² S₂ = (T − S₁)² / S₂. Landmarks snap to the nearest node.
class PaperQuadraticBar1D {
 public:
  /// setup.attachment_X must be {0, 1} (see paper_setup_error).
  PaperQuadraticBar1D(int num_elements, Plastic1DSetup setup);

  int num_elements() const { return n_; }
  double h() const { return 1.0 / n_; }
  const Plastic1DSetup& setup() const { return setup_; }
  const std::vector<int>& landmark_nodes() const { return landmark_nodes_; }

  /// c(p) of eq. 27 (dimensionless when p is).
  double equilibrium_coefficient(const Eigen::VectorXd& p) const;
  /// x(p) (N+1): the minimiser of E(·, p) under the hard attachments.
  Eigen::VectorXd positions(const Eigen::VectorXd& p) const;
  /// dx/dp (N+1 x N), exact.
  Eigen::MatrixXd positions_jacobian(const Eigen::VectorXd& p) const;
  /// E(x, p) for any x (N+1), and ∂E/∂x (N+1): zero at interior nodes of x(p).
  double elastic_energy(const Eigen::VectorXd& x, const Eigen::VectorXd& p) const;
  Eigen::VectorXd elastic_gradient_x(const Eigen::VectorXd& x, const Eigen::VectorXd& p) const;
  /// E(x(p), p) = (T − S₁)² / S₂ and its total gradient dE/dp (N).
  double equilibrium_elastic_energy(const Eigen::VectorXd& p) const;
  Eigen::VectorXd equilibrium_elastic_gradient(const Eigen::VectorXd& p) const;
  /// Φ(p) = ‖W p‖² + α Σ_l (x_l(p) − y_l)² + β E(x(p), p) (eq. 26) and its exact gradient (N).
  double objective(const Eigen::VectorXd& p, double alpha, double beta,
                   Smoothness1DOrder order) const;
  Eigen::VectorXd objective_gradient(const Eigen::VectorXd& p, double alpha, double beta,
                                     Smoothness1DOrder order) const;
  /// Residuals r(p) with Φ = ‖r‖² = [W p; √α (x_l − y_l); √β (T − S₁)/√S₂], and dr/dp.
  Eigen::VectorXd residuals(const Eigen::VectorXd& p, double alpha, double beta,
                            Smoothness1DOrder order) const;
  Eigen::MatrixXd residual_jacobian(const Eigen::VectorXd& p, double alpha, double beta,
                                    Smoothness1DOrder order) const;

 private:
  int n_;
  Plastic1DSetup setup_;
  std::vector<int> landmark_nodes_;
  Eigen::MatrixXd w_first_, w_second_;
};

/// Empty when the setup suits PaperQuadraticBar1D (two attachments, at X = 0 and X = 1).
std::optional<std::string> paper_setup_error(const Plastic1DSetup& setup);

/// Which energy and equilibrium the registration uses (see the file comment).
enum class Plastic1DModel {
  kPaperQuadratic,    ///< eqs. 26–27: ∫ (ẋ/f_p − 1)², hard attachments, explicit x(p)
  kStableNeoHookean,  ///< stable neo-Hookean V ψ(F/s), attachment springs, Newton equilibrium
};
const char* to_string(Plastic1DModel model);

struct Plastic1DOptions {
  /// The plastic model: eqs. 26–27 verbatim (default) or the stable neo-Hookean bar.
  Plastic1DModel model = Plastic1DModel::kPaperQuadratic;
  /// The smoothness S(p): first order ∫ ḟ_p² (eq. 26, default) or second order ‖L p‖².
  Smoothness1DOrder smoothness = Smoothness1DOrder::kFirst;
  /// Elements of the bar; a multiple of 4 in [8, 2000]. Results are N-converged from N ≈ 200.
  int num_elements = 200;
  /// Material (Pa), kStableNeoHookean only; the equilibrium under hard-ish attachments hardly
  /// depends on it.
  Psi1D psi{};
  /// Attachment spring stiffness k (N per unit length of displacement), > 0; kStableNeoHookean
  /// only (kPaperQuadratic attachments are hard). Stiff: attachments are nearly hard.
  double attachment_stiffness = 1e4;
  /// Landmark weight α (eqs. 3, 26), > 0: large means the landmarks are met closely (landmark
  /// error ≈ 10/α for kPaperQuadratic with β = 1).
  double alpha = 1e6;
  /// kPaperQuadratic: the elastic-energy weight β of eq. 26, > 0; it alone fixes the scale of f_p
  /// (β → 0 lets f_p → 0 with c → ∞: no minimiser), β → ∞ turns eq. 26 into the r = 2
  /// variational problem. kStableNeoHookean: the attachment-energy weight of eq. 3, ≥ 0.
  double beta = 1.0;
  /// Gauss–Newton / Levenberg–Marquardt iterations, ≥ 1 (small β needs ~1000 for kPaperQuadratic).
  int max_iterations = 3000;
  /// kStableNeoHookean: stop when the relative objective decrease of an iteration is below this;
  /// in [0, 1).
  double relative_decrease_tolerance = 1e-12;
  /// kPaperQuadratic: stop when ‖∇Φ‖∞ ≤ gradient_tolerance · max(1, Φ), or when no damped step
  /// decreases Φ and ‖∇Φ‖∞ ≤ 100 · gradient_tolerance · max(1, Φ) (round-off); > 0.
  double gradient_tolerance = 1e-9;
  /// kStableNeoHookean: Levenberg damping added to the Gauss–Newton normal matrix (relative to its
  /// mean diagonal); ≥ 0. Only guards the singular smoothness operator; tiny.
  double damping = 1e-12;
  /// Newton iterations per equilibrium solve, ≥ 1; and its tolerance on ‖∂Π/∂x‖∞ (N), > 0.
  int max_newton_iterations = 50;
  double newton_tolerance = 1e-10;
  /// Trial steps whose plastic stretch drops below this are shortened; in (0, 1).
  double min_plastic_stretch = 1e-3;

  /// Empty when valid; otherwise one line naming the field, its value and the constraint.
  std::optional<std::string> validate() const;
};

enum class Plastic1DStatus {
  kConverged,          ///< relative decrease below tolerance
  kMaxIterations,      ///< iteration limit reached first
  kLineSearchFailed,   ///< no step along the Gauss–Newton direction decreased the objective
  kEquilibriumFailed,  ///< Newton did not reach the equilibrium tolerance
  kInvalidOptions,     ///< Options::validate() failed (see Summary::message)
};
const char* to_string(Plastic1DStatus status);

struct Plastic1DSummary {
  Plastic1DStatus status = Plastic1DStatus::kInvalidOptions;
  std::string message;  ///< validation message, empty otherwise
  int iterations = 0;   ///< Gauss–Newton (or Levenberg–Marquardt) iterations taken
  int equilibrium_solves = 0;
  int newton_iterations = 0;  ///< summed over all equilibrium solves
  double initial_objective = 0.0, final_objective = 0.0;
  /// Final, unweighted: S(p), Σ_l (x_l − y_l)², E_a (kStableNeoHookean) and E (kPaperQuadratic).
  double smoothness_term = 0.0, landmark_term = 0.0, attachment_term = 0.0, elastic_term = 0.0;
  double final_gradient_norm = 0.0;  ///< ‖∇Φ‖∞ at the end (kPaperQuadratic)
  double max_landmark_error = 0.0;   ///< max_l |x_l − y_l| at the end (world units)
  double seconds = 0.0, equilibrium_seconds = 0.0;

  bool converged() const { return status == Plastic1DStatus::kConverged; }
  std::string brief_report() const;
  std::string full_report() const;
};

struct Plastic1DResult {
  Eigen::VectorXd X;  ///< rest node coordinates (N+1)
  Eigen::VectorXd x;  ///< equilibrium positions (N+1)
  Eigen::VectorXd s;  ///< plastic stretches f_p per element (N)
  Plastic1DSummary summary;
};

/// Runs the plastic-strain registration of Fig. 23 from p = 1 (x = 2X for kPaperQuadratic).
Plastic1DResult solve_plastic_1d(const Plastic1DOptions& options, const Plastic1DSetup& setup = {});

struct Variational1DOptions {
  int num_elements = 200;  ///< as Plastic1DOptions::num_elements
  int order = 2;           ///< r of eq. 25, in {1, 2, 3}: the energy ∫ (d^r x / dX^r)²
  double alpha = 1e6;      ///< landmark weight α of eq. 25, > 0
  std::optional<std::string> validate() const;
};

/// Eq. 25 (discrete): min Σ h (D_r x)² + α Σ_l (x_l − y_l)² with x fixed at the attachments.
/// Returns N+1 positions, or std::nullopt for invalid options.
std::optional<Eigen::VectorXd> solve_variational_1d(const Variational1DOptions& options,
                                                    const Plastic1DSetup& setup = {});

/// Least-squares slope of x over the nodes in [a + margin·h, b − margin·h].
double fitted_slope(const Eigen::VectorXd& X, const Eigen::VectorXd& x, double a, double b,
                    int margin);

/// How well a deformed profile x(X) matches Fig. 23's piecewise-linear target, per subinterval
/// between consecutive constraint points (sorted attachment and landmark X: [0, ¼], [¼, ½], [½,
/// 1]).
struct Fig23Metrics {
  std::vector<double> bounds;        ///< subinterval end points (K+1)
  std::vector<double> target_slope;  ///< slope implied by the constraints (K): 1, 5, 1
  std::vector<double> chord_slope;   ///< (x(b) − x(a)) / (b − a): equals the target once the
                                     ///< landmarks are met, so it cannot tell profiles apart
  std::vector<double> fitted_slope;  ///< least-squares slope over [a + margin, b − margin]
  std::vector<double> min_local_slope, max_local_slope;  ///< of ẋ = d_e / h over the subinterval
  double max_landmark_error = 0.0;                       ///< max_l |x_l − y_l| (world units)
  double min_x = 0.0, max_x = 0.0;                       ///< range of x
  bool monotone = false;                                 ///< every d_e ≥ 0
  /// How far x leaves the attachment range [t₀, t₁] (≥ 0): the variational overshoot.
  double overshoot = 0.0;
  /// max_k |fitted_slope_k / target_slope_k − 1|.
  double max_relative_fitted_slope_error() const;
};

/// Measures x (N+1, on nodes X) against setup; margin is rest length cut from both ends of each
/// subinterval before the least-squares fit (≥ 0, smaller than half the shortest subinterval).
Fig23Metrics measure_fig23(const Eigen::VectorXd& X, const Eigen::VectorXd& x,
                           const Plastic1DSetup& setup = {}, double margin = 0.025);

/// One row of the Fig. 23 comparison: a plastic solve (order == 0) or a variational one (r ≥ 1).
struct Fig23Row {
  std::string method;              ///< "plastic" or "variational r=<r>"
  int order = 0;                   ///< r of eq. 25, 0 for the plastic method
  double alpha = 0.0, beta = 0.0;  ///< β only for the plastic method
  int num_elements = 0;
  std::string status;  ///< plastic: to_string(Plastic1DStatus); variational: "solved"
  double min_fp = 0.0, max_fp = 0.0;  ///< plastic only
  Fig23Metrics metrics;
};

/// The plastic method (options with each α, β, N substituted) and the r = 1, 2, 3 baselines (each
/// α, N) on Fig. 23's setup. Rows in that order; each solve is independent.
std::vector<Fig23Row> fig23_table(const Plastic1DOptions& options,
                                  const std::vector<double>& alphas,
                                  const std::vector<double>& betas,
                                  const std::vector<int>& element_counts, double margin = 0.025);
/// One line per row: method, α, β, N, chord / fitted slopes, local-slope ranges, landmark error,
/// monotone, overshoot.
std::string format_fig23_table(const std::vector<Fig23Row>& rows);

}  // namespace sinew::offline::experiments
