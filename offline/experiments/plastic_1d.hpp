#pragma once
/// Seed 003 §4.5 / Fig. 23: the 1D comparison of plastic-strain registration with a variational
/// (second-order) shape-modelling baseline. A bar with rest shape [0, 1] is split into N equal
/// elements; element e has a plastic stretch s_e (the 1D F_p) and the elastic energy (eq. 1)
///   E_e(x, s) = V(s_e) ψ(F_e / s_e),  V = s_e h (V = |F_p| V₀),  F_e = (x_{e+1} − x_e) / h,
/// with ψ the 1D restriction of the stable neo-Hookean energy [Smith et al. 2018] (I_C = f², J =
/// f),
///   ψ(f) = μ/2 (f² − 1) − μ/2 ln((f² + 1)/2) + λ/2 (f − a)² − λ/2 (1 − a)²,  a = 1 + μ/(2λ),
/// so that ψ(1) = ψ'(1) = 0 and ψ'' ≥ λ > 0 for every f (also inverted, f ≤ 0).
/// Attachments (X = 0 → 0, X = 1 → 2) are stiff springs E_a = Σ k/2 (x_a − t_a)² (appendix F);
/// landmarks are X = 1/4 → 1/4 and X = 1/2 → 3/2. The registration (eqs. 3–4) is
///   min_s ‖L s‖² + α Σ_l (x_l − y_l)² + β E_a(x)   s.t.  ∂E/∂x (x, s) + ∂E_a/∂x (x) = 0,
/// with L the combinatorial Laplacian on element adjacency (appendix A, [Zhang 2004]) and the
/// equilibrium solved by Newton for each s; s is updated by Gauss–Newton with x linearised as
/// x(s + Δs) ≈ x + J Δs, J = −K⁻¹ ∂f/∂s (eqs. 8–10), and a backtracking line search along Δs.
/// The baseline is eq. 25 with r = 2: min ∫ (x'')² + α landmark misfit, hard attachments,
/// discretised by second differences on the same nodes. Dense Eigen algebra: N is small.

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

struct Plastic1DOptions {
  /// Elements of the bar; a multiple of 4 in [8, 2000]. More elements sharpen the kinks.
  int num_elements = 200;
  /// Material (Pa); the equilibrium under hard-ish attachments hardly depends on it.
  Psi1D psi{};
  /// Attachment spring stiffness k (N per unit length of displacement), > 0. Stiff: attachments
  /// are nearly hard, as in Fig. 23.
  double attachment_stiffness = 1e4;
  /// Landmark weight α (eq. 3), > 0: large means the landmarks are met closely.
  double alpha = 1e6;
  /// Attachment-energy weight β (eq. 3), ≥ 0: keeps s from collapsing (the gauge s → c s leaves
  /// x nearly unchanged); small so it does not compete with the landmarks.
  double beta = 1.0;
  /// Gauss–Newton iterations, ≥ 1.
  int max_iterations = 100;
  /// Stop when the relative objective decrease of an iteration is below this; in [0, 1).
  double relative_decrease_tolerance = 1e-12;
  /// Levenberg damping added to the Gauss–Newton normal matrix (relative to its mean diagonal);
  /// ≥ 0. Only guards the singular L²; tiny.
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
  int iterations = 0;   ///< Gauss–Newton iterations taken
  int equilibrium_solves = 0;
  int newton_iterations = 0;  ///< summed over all equilibrium solves
  double initial_objective = 0.0, final_objective = 0.0;
  double laplacian_term = 0.0, landmark_term = 0.0, attachment_term = 0.0;  ///< final, unweighted
  double max_landmark_error = 0.0;  ///< max_l |x_l − y_l| at the end (world units)
  double seconds = 0.0, equilibrium_seconds = 0.0;

  bool converged() const { return status == Plastic1DStatus::kConverged; }
  std::string brief_report() const;
  std::string full_report() const;
};

struct Plastic1DResult {
  Eigen::VectorXd X;  ///< rest node coordinates (N+1)
  Eigen::VectorXd x;  ///< equilibrium positions (N+1)
  Eigen::VectorXd s;  ///< plastic stretches (N)
  Plastic1DSummary summary;
};

/// Runs the plastic-strain registration of Fig. 23 from s = 1.
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

}  // namespace sinew::offline::experiments
