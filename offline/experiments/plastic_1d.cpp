#include "offline/experiments/plastic_1d.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

namespace sinew::offline::experiments {
namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

int nearest_node(double X, int n) {
  return std::clamp(static_cast<int>(std::lround(X * n)), 0, n);
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// ψ: 1D stable neo-Hookean. a = 1 + μ/(2λ) makes f = 1 stress-free (μ − μ/2 + λ(1 − a) = 0).

double Psi1D::value(double f) const {
  const double a = 1.0 + mu / (2.0 * lambda);
  return 0.5 * mu * (f * f - 1.0) - 0.5 * mu * std::log(0.5 * (f * f + 1.0)) +
         0.5 * lambda * ((f - a) * (f - a) - (1.0 - a) * (1.0 - a));
}
double Psi1D::first(double f) const {
  const double a = 1.0 + mu / (2.0 * lambda);
  return mu * f - mu * f / (f * f + 1.0) + lambda * (f - a);
}
double Psi1D::second(double f) const {
  const double q = f * f + 1.0;
  return mu - mu * (1.0 - f * f) / (q * q) + lambda;
}

// ---------------------------------------------------------------------------------------------
// The bar. Per element, with d = x_{e+1} − x_e and f = d/(h s): E_e = s h ψ(f),
// ∂E/∂d = ψ'(f), ∂E/∂s = h(ψ − f ψ'), ∂²E/∂d² = ψ''/(h s), ∂²E/∂d∂s = −f ψ''/s,
// ∂²E/∂s² = h f² ψ''/s.

PlasticBar1D::PlasticBar1D(int num_elements, Psi1D psi, double attachment_stiffness,
                           Plastic1DSetup setup)
    : n_(num_elements), psi_(psi), k_(attachment_stiffness), setup_(std::move(setup)) {
  for (double X : setup_.attachment_X) attachment_nodes_.push_back(nearest_node(X, n_));
  for (double X : setup_.landmark_X) landmark_nodes_.push_back(nearest_node(X, n_));
}

double PlasticBar1D::attachment_energy(const Eigen::VectorXd& x) const {
  double e = 0.0;
  for (size_t a = 0; a < attachment_nodes_.size(); ++a) {
    const double r = x[attachment_nodes_[a]] - setup_.attachment_target[a];
    e += 0.5 * k_ * r * r;
  }
  return e;
}

double PlasticBar1D::energy(const Eigen::VectorXd& x, const Eigen::VectorXd& s) const {
  double e = attachment_energy(x);
  for (int i = 0; i < n_; ++i) e += s[i] * h() * psi_.value((x[i + 1] - x[i]) / (h() * s[i]));
  return e;
}

Eigen::VectorXd PlasticBar1D::gradient_x(const Eigen::VectorXd& x, const Eigen::VectorXd& s) const {
  Eigen::VectorXd g = Eigen::VectorXd::Zero(n_ + 1);
  for (int i = 0; i < n_; ++i) {
    const double p = psi_.first((x[i + 1] - x[i]) / (h() * s[i]));
    g[i] -= p;
    g[i + 1] += p;
  }
  for (size_t a = 0; a < attachment_nodes_.size(); ++a) {
    const int v = attachment_nodes_[a];
    g[v] += k_ * (x[v] - setup_.attachment_target[a]);
  }
  return g;
}

Eigen::VectorXd PlasticBar1D::gradient_s(const Eigen::VectorXd& x, const Eigen::VectorXd& s) const {
  Eigen::VectorXd g(n_);
  for (int i = 0; i < n_; ++i) {
    const double f = (x[i + 1] - x[i]) / (h() * s[i]);
    g[i] = h() * (psi_.value(f) - f * psi_.first(f));
  }
  return g;
}

Eigen::MatrixXd PlasticBar1D::hessian_xx(const Eigen::VectorXd& x, const Eigen::VectorXd& s) const {
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(n_ + 1, n_ + 1);
  for (int i = 0; i < n_; ++i) {
    const double kd = psi_.second((x[i + 1] - x[i]) / (h() * s[i])) / (h() * s[i]);
    K(i, i) += kd;
    K(i + 1, i + 1) += kd;
    K(i, i + 1) -= kd;
    K(i + 1, i) -= kd;
  }
  for (int v : attachment_nodes_) K(v, v) += k_;
  return K;
}

Eigen::MatrixXd PlasticBar1D::hessian_xs(const Eigen::VectorXd& x, const Eigen::VectorXd& s) const {
  Eigen::MatrixXd B = Eigen::MatrixXd::Zero(n_ + 1, n_);
  for (int i = 0; i < n_; ++i) {
    const double f = (x[i + 1] - x[i]) / (h() * s[i]);
    const double m = -f * psi_.second(f) / s[i];
    B(i, i) -= m;
    B(i + 1, i) += m;
  }
  return B;
}

Eigen::MatrixXd PlasticBar1D::hessian_ss(const Eigen::VectorXd& x, const Eigen::VectorXd& s) const {
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(n_, n_);
  for (int i = 0; i < n_; ++i) {
    const double f = (x[i + 1] - x[i]) / (h() * s[i]);
    H(i, i) = h() * f * f * psi_.second(f) / s[i];
  }
  return H;
}

Eigen::MatrixXd PlasticBar1D::plastic_strain_laplacian() const {
  Eigen::MatrixXd L = Eigen::MatrixXd::Zero(n_, n_);
  for (int e = 0; e + 1 < n_; ++e) {  // each adjacency (e, e+1) contributes to both rows
    L(e, e + 1) += 1.0;
    L(e, e) -= 1.0;
    L(e + 1, e) += 1.0;
    L(e + 1, e + 1) -= 1.0;
  }
  return L;
}

// ---------------------------------------------------------------------------------------------

std::optional<std::string> Plastic1DOptions::validate() const {
  std::ostringstream m;
  if (num_elements < 8 || num_elements > 2000 || num_elements % 4 != 0)
    m << "num_elements = " << num_elements << " must be a multiple of 4 in [8, 2000]";
  else if (!(psi.mu > 0) || !(psi.lambda > 0))
    m << "psi = (" << psi.mu << ", " << psi.lambda << ") must have mu > 0 and lambda > 0";
  else if (!(attachment_stiffness > 0))
    m << "attachment_stiffness = " << attachment_stiffness << " must be > 0";
  else if (!(alpha > 0))
    m << "alpha = " << alpha << " must be > 0";
  else if (!(beta >= 0))
    m << "beta = " << beta << " must be >= 0";
  else if (max_iterations < 1)
    m << "max_iterations = " << max_iterations << " must be >= 1";
  else if (!(relative_decrease_tolerance >= 0 && relative_decrease_tolerance < 1))
    m << "relative_decrease_tolerance = " << relative_decrease_tolerance << " must be in [0, 1)";
  else if (!(damping >= 0))
    m << "damping = " << damping << " must be >= 0";
  else if (max_newton_iterations < 1)
    m << "max_newton_iterations = " << max_newton_iterations << " must be >= 1";
  else if (!(newton_tolerance > 0))
    m << "newton_tolerance = " << newton_tolerance << " must be > 0";
  else if (!(min_plastic_stretch > 0 && min_plastic_stretch < 1))
    m << "min_plastic_stretch = " << min_plastic_stretch << " must be in (0, 1)";
  if (m.str().empty()) return std::nullopt;
  return m.str();
}

const char* to_string(Plastic1DStatus status) {
  switch (status) {
    case Plastic1DStatus::kConverged:
      return "converged";
    case Plastic1DStatus::kMaxIterations:
      return "max iterations";
    case Plastic1DStatus::kLineSearchFailed:
      return "line search failed";
    case Plastic1DStatus::kEquilibriumFailed:
      return "equilibrium failed";
    case Plastic1DStatus::kInvalidOptions:
      return "invalid options";
  }
  return "unknown";
}

std::string Plastic1DSummary::brief_report() const {
  std::ostringstream o;
  o << "Plastic1D: " << to_string(status) << ", " << iterations << " GN iterations, objective "
    << initial_objective << " -> " << final_objective << ", max landmark error "
    << max_landmark_error << ", " << seconds << " s";
  return o.str();
}

std::string Plastic1DSummary::full_report() const {
  std::ostringstream o;
  o << brief_report() << "\n"
    << "  message: " << (message.empty() ? "-" : message) << "\n"
    << "  equilibrium solves: " << equilibrium_solves << " (" << newton_iterations
    << " Newton iterations, " << equilibrium_seconds << " s)\n"
    << "  final terms: |Ls|^2 = " << laplacian_term << ", landmark misfit^2 = " << landmark_term
    << ", E_a = " << attachment_term << "\n";
  return o.str();
}

namespace {

/// Newton on Π(·, s) from x (in place); convex in x (ψ'' > 0, s > 0), so a plain backtracking on
/// Π suffices. Returns true when ‖∂Π/∂x‖∞ ≤ tolerance.
bool solve_equilibrium(const PlasticBar1D& bar, const Eigen::VectorXd& s, Eigen::VectorXd& x,
                       const Plastic1DOptions& o, Plastic1DSummary& summary) {
  const auto t0 = Clock::now();
  ++summary.equilibrium_solves;
  bool ok = false;
  for (int it = 0; it < o.max_newton_iterations; ++it) {
    const Eigen::VectorXd g = bar.gradient_x(x, s);
    if (!g.allFinite()) break;
    if (g.lpNorm<Eigen::Infinity>() <= o.newton_tolerance) {
      ok = true;
      break;
    }
    ++summary.newton_iterations;
    const Eigen::VectorXd dx = bar.hessian_xx(x, s).ldlt().solve(-g);
    const double e0 = bar.energy(x, s);
    double t = 1.0;
    for (int ls = 0; ls < 40; ++ls, t *= 0.5) {
      if (bar.energy(x + t * dx, s) <= e0 + 1e-4 * t * g.dot(dx)) break;
    }
    x += t * dx;
  }
  summary.equilibrium_seconds += seconds_since(t0);
  return ok;
}

struct Terms {
  double laplacian = 0, landmark = 0, attachment = 0, max_landmark_error = 0;
};

Terms evaluate_terms(const PlasticBar1D& bar, const Eigen::MatrixXd& L, const Eigen::VectorXd& x,
                     const Eigen::VectorXd& s) {
  Terms t;
  t.laplacian = (L * s).squaredNorm();
  for (size_t l = 0; l < bar.landmark_nodes().size(); ++l) {
    const double r = x[bar.landmark_nodes()[l]] - bar.setup().landmark_target[l];
    t.landmark += r * r;
    t.max_landmark_error = std::max(t.max_landmark_error, std::abs(r));
  }
  t.attachment = bar.attachment_energy(x);
  return t;
}

double objective(const Terms& t, const Plastic1DOptions& o) {
  return t.laplacian + o.alpha * t.landmark + o.beta * t.attachment;
}

}  // namespace

Plastic1DResult solve_plastic_1d(const Plastic1DOptions& o, const Plastic1DSetup& setup) {
  const auto t0 = Clock::now();
  Plastic1DResult result;
  Plastic1DSummary& sum = result.summary;
  if (auto msg = o.validate()) {
    sum.message = *msg;
    return result;
  }
  const int n = o.num_elements;
  const PlasticBar1D bar(n, o.psi, o.attachment_stiffness, setup);
  const Eigen::MatrixXd L = bar.plastic_strain_laplacian();
  result.X = Eigen::VectorXd::LinSpaced(n + 1, 0.0, 1.0);
  result.s = Eigen::VectorXd::Ones(n);
  result.x = result.X;
  Eigen::VectorXd& s = result.s;
  Eigen::VectorXd& x = result.x;

  if (!solve_equilibrium(bar, s, x, o, sum)) {
    sum.status = Plastic1DStatus::kEquilibriumFailed;
    sum.seconds = seconds_since(t0);
    return result;
  }
  Terms terms = evaluate_terms(bar, L, x, s);
  double phi = objective(terms, o);
  sum.initial_objective = phi;
  sum.status = Plastic1DStatus::kMaxIterations;

  // Residual r(s) = [L s; √α (S x − y); √(βk/2) (A x − t)], Φ = ‖r‖² (eq. 6 with E_a quadratic).
  const int q = static_cast<int>(bar.landmark_nodes().size());
  const int p = static_cast<int>(bar.attachment_nodes().size());
  const double wa = std::sqrt(o.alpha), wb = std::sqrt(0.5 * o.beta * o.attachment_stiffness);
  for (int it = 0; it < o.max_iterations; ++it) {
    // J = dx/ds = −K⁻¹ ∂²Π/∂x∂s (eq. 10), by differentiating the equilibrium.
    const Eigen::MatrixXd J = -bar.hessian_xx(x, s).ldlt().solve(bar.hessian_xs(x, s));
    Eigen::MatrixXd Jr(L.rows() + q + p, n);
    Eigen::VectorXd r(L.rows() + q + p);
    Jr.topRows(L.rows()) = L;
    r.head(L.rows()) = L * s;
    for (int l = 0; l < q; ++l) {
      const int v = bar.landmark_nodes()[l];
      Jr.row(L.rows() + l) = wa * J.row(v);
      r[L.rows() + l] = wa * (x[v] - setup.landmark_target[l]);
    }
    for (int a = 0; a < p; ++a) {
      const int v = bar.attachment_nodes()[a];
      Jr.row(L.rows() + q + a) = wb * J.row(v);
      r[L.rows() + q + a] = wb * (x[v] - setup.attachment_target[a]);
    }
    // Gauss–Newton step (eqs. 8–9): (JrᵀJr + εI) Δs = −Jrᵀ r.
    Eigen::MatrixXd H = Jr.transpose() * Jr;
    H.diagonal().array() += o.damping * H.diagonal().mean();
    const Eigen::VectorXd ds = H.ldlt().solve(-Jr.transpose() * r);
    ++sum.iterations;

    // Backtracking line search on η (the paper uses Brent's method): equilibrium at s + η Δs.
    double eta = 1.0;
    while (((s + eta * ds).array() < o.min_plastic_stretch).any()) eta *= 0.5;
    bool accepted = false;
    for (int ls = 0; ls < 40; ++ls, eta *= 0.5) {
      const Eigen::VectorXd s_try = s + eta * ds;
      Eigen::VectorXd x_try = x + eta * (J * ds);  // linearised prediction as the Newton start
      if (!solve_equilibrium(bar, s_try, x_try, o, sum)) continue;
      const Terms t_try = evaluate_terms(bar, L, x_try, s_try);
      const double phi_try = objective(t_try, o);
      if (phi_try < phi) {
        const double decrease = (phi - phi_try) / std::max(phi, 1e-300);
        s = s_try;
        x = x_try;
        phi = phi_try;
        terms = t_try;
        accepted = true;
        if (decrease < o.relative_decrease_tolerance) sum.status = Plastic1DStatus::kConverged;
        break;
      }
    }
    if (!accepted) {
      // No decrease along Δs: at a (numerical) stationary point when the step is negligible.
      sum.status = ds.norm() <= 1e-10 * std::max(1.0, s.norm())
                       ? Plastic1DStatus::kConverged
                       : Plastic1DStatus::kLineSearchFailed;
    }
    if (sum.status != Plastic1DStatus::kMaxIterations) break;
  }
  sum.final_objective = phi;
  sum.laplacian_term = terms.laplacian;
  sum.landmark_term = terms.landmark;
  sum.attachment_term = terms.attachment;
  sum.max_landmark_error = terms.max_landmark_error;
  sum.seconds = seconds_since(t0);
  return result;
}

// ---------------------------------------------------------------------------------------------

std::optional<std::string> Variational1DOptions::validate() const {
  std::ostringstream m;
  if (num_elements < 8 || num_elements > 2000 || num_elements % 4 != 0)
    m << "num_elements = " << num_elements << " must be a multiple of 4 in [8, 2000]";
  else if (order < 1 || order > 3)
    m << "order = " << order << " must be 1, 2 or 3";
  else if (!(alpha > 0))
    m << "alpha = " << alpha << " must be > 0";
  if (m.str().empty()) return std::nullopt;
  return m.str();
}

std::optional<Eigen::VectorXd> solve_variational_1d(const Variational1DOptions& o,
                                                    const Plastic1DSetup& setup) {
  if (o.validate()) return std::nullopt;
  const int n = o.num_elements;
  const double h = 1.0 / n;
  // D_r: r-th forward difference / h^r, rows i = 0..n−r; the quadrature weight is h.
  const int rows = n + 1 - o.order;
  Eigen::MatrixXd D = Eigen::MatrixXd::Zero(rows, n + 1);
  const double stencil[3][4] = {{-1, 1, 0, 0}, {1, -2, 1, 0}, {-1, 3, -3, 1}};
  for (int i = 0; i < rows; ++i)
    for (int j = 0; j <= o.order; ++j) D(i, i + j) = stencil[o.order - 1][j] / std::pow(h, o.order);
  const int c = static_cast<int>(setup.attachment_X.size());
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(n + 1 + c, n + 1 + c);
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n + 1 + c);
  K.topLeftCorner(n + 1, n + 1) = 2.0 * h * D.transpose() * D;
  for (size_t l = 0; l < setup.landmark_X.size(); ++l) {
    const int v = nearest_node(setup.landmark_X[l], n);
    K(v, v) += 2.0 * o.alpha;
    rhs[v] += 2.0 * o.alpha * setup.landmark_target[l];
  }
  for (int a = 0; a < c; ++a) {  // hard attachments as Lagrange multipliers (KKT)
    const int v = nearest_node(setup.attachment_X[a], n);
    K(n + 1 + a, v) = K(v, n + 1 + a) = 1.0;
    rhs[n + 1 + a] = setup.attachment_target[a];
  }
  return Eigen::VectorXd(K.partialPivLu().solve(rhs).head(n + 1));
}

double fitted_slope(const Eigen::VectorXd& X, const Eigen::VectorXd& x, double a, double b,
                    int margin) {
  const double h = X[1] - X[0];
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  int m = 0;
  for (Eigen::Index i = 0; i < X.size(); ++i) {
    if (X[i] < a + margin * h - 1e-12 || X[i] > b - margin * h + 1e-12) continue;
    sx += X[i];
    sy += x[i];
    sxx += X[i] * X[i];
    sxy += X[i] * x[i];
    ++m;
  }
  return (m * sxy - sx * sy) / (m * sxx - sx * sx);
}

}  // namespace sinew::offline::experiments
