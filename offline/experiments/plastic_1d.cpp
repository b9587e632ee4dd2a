#include "offline/experiments/plastic_1d.hpp"
#include "common/timing.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>
#include <utility>

namespace sinew::offline::experiments {
namespace {

using Clock = std::chrono::steady_clock;
using common::seconds_since;

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
  return smoothness_matrix(n_, Smoothness1DOrder::kSecond);
}

Eigen::MatrixXd smoothness_matrix(int n, Smoothness1DOrder order) {
  if (order == Smoothness1DOrder::kFirst) {
    // ∫ ḟ_p² with ḟ_p ≈ (p_{e+1} − p_e)/h on a cell of length h: rows (p_{e+1} − p_e)/√h.
    const double w = std::sqrt(static_cast<double>(n));
    Eigen::MatrixXd D = Eigen::MatrixXd::Zero(n - 1, n);
    for (int e = 0; e + 1 < n; ++e) {
      D(e, e) = -w;
      D(e, e + 1) = w;
    }
    return D;
  }
  Eigen::MatrixXd L = Eigen::MatrixXd::Zero(n, n);
  for (int e = 0; e + 1 < n; ++e) {  // each adjacency (e, e+1) contributes to both rows
    L(e, e + 1) += 1.0;
    L(e, e) -= 1.0;
    L(e + 1, e) += 1.0;
    L(e + 1, e + 1) -= 1.0;
  }
  return L;
}

const char* to_string(Smoothness1DOrder order) {
  return order == Smoothness1DOrder::kFirst ? "first order" : "second order";
}

const char* to_string(Plastic1DModel model) {
  return model == Plastic1DModel::kPaperQuadratic ? "paper quadratic" : "stable neo-Hookean";
}

// ---------------------------------------------------------------------------------------------
// Eqs. 26–27. With d_e = h p_e (1 + c p_e): dc/dp_j = −h (1 + 2 c p_j) / S₂, so
// dx_i/dp_j = h (1 + 2 c p_j) [j < i] + h P_i dc/dp_j with P_i = Σ_{e<i} p_e².

std::optional<std::string> paper_setup_error(const Plastic1DSetup& setup) {
  if (setup.attachment_X.size() != 2 || setup.attachment_target.size() != 2 ||
      setup.attachment_X[0] != 0.0 || setup.attachment_X[1] != 1.0)
    return std::string(
        "setup.attachment_X must be {0, 1} (hard end attachments) for "
        "Plastic1DModel::kPaperQuadratic");
  if (setup.landmark_X.size() != setup.landmark_target.size())
    return std::string("setup.landmark_X and setup.landmark_target differ in size");
  return std::nullopt;
}

PaperQuadraticBar1D::PaperQuadraticBar1D(int num_elements, Plastic1DSetup setup)
    : n_(num_elements),
      setup_(std::move(setup)),
      w_first_(smoothness_matrix(num_elements, Smoothness1DOrder::kFirst)),
      w_second_(smoothness_matrix(num_elements, Smoothness1DOrder::kSecond)) {
  for (double X : setup_.landmark_X) landmark_nodes_.push_back(nearest_node(X, n_));
}

double PaperQuadraticBar1D::equilibrium_coefficient(const Eigen::VectorXd& p) const {
  const double T = setup_.attachment_target[1] - setup_.attachment_target[0];
  return (T - h() * p.sum()) / (h() * p.squaredNorm());
}

Eigen::VectorXd PaperQuadraticBar1D::positions(const Eigen::VectorXd& p) const {
  const double c = equilibrium_coefficient(p);
  Eigen::VectorXd x(n_ + 1);
  x[0] = setup_.attachment_target[0];
  for (int e = 0; e < n_; ++e) x[e + 1] = x[e] + h() * p[e] * (1.0 + c * p[e]);
  x[n_] = setup_.attachment_target[1];  // equal up to round-off; keep the attachment exact
  return x;
}

Eigen::MatrixXd PaperQuadraticBar1D::positions_jacobian(const Eigen::VectorXd& p) const {
  const double c = equilibrium_coefficient(p);
  const double S2 = h() * p.squaredNorm();
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(n_ + 1, n_);
  double P = 0.0;  // Σ_{e<i} p_e²
  for (int i = 1; i < n_; ++i) {
    P += p[i - 1] * p[i - 1];
    for (int j = 0; j < n_; ++j) {
      const double dc = -h() * (1.0 + 2.0 * c * p[j]) / S2;
      J(i, j) = (j < i ? h() * (1.0 + 2.0 * c * p[j]) : 0.0) + h() * P * dc;
    }
  }
  return J;  // rows 0 and N (the attachments) are zero
}

double PaperQuadraticBar1D::elastic_energy(const Eigen::VectorXd& x,
                                           const Eigen::VectorXd& p) const {
  double e = 0.0;
  for (int i = 0; i < n_; ++i) {
    const double r = (x[i + 1] - x[i]) / (h() * p[i]) - 1.0;
    e += h() * r * r;
  }
  return e;
}

Eigen::VectorXd PaperQuadraticBar1D::elastic_gradient_x(const Eigen::VectorXd& x,
                                                        const Eigen::VectorXd& p) const {
  Eigen::VectorXd g = Eigen::VectorXd::Zero(n_ + 1);
  for (int i = 0; i < n_; ++i) {
    const double dd = 2.0 * ((x[i + 1] - x[i]) / (h() * p[i]) - 1.0) / p[i];
    g[i] -= dd;
    g[i + 1] += dd;
  }
  return g;
}

namespace {
/// q = (T − S₁)/√S₂ (so E = q²) and dq/dp.
double elastic_residual(const PaperQuadraticBar1D& bar, const Eigen::VectorXd& p,
                        Eigen::VectorXd* gradient) {
  const double h = bar.h();
  const double T = bar.setup().attachment_target[1] - bar.setup().attachment_target[0];
  const double S1 = h * p.sum(), S2 = h * p.squaredNorm();
  const double q = (T - S1) / std::sqrt(S2);
  if (gradient)
    *gradient = (-h / std::sqrt(S2)) * Eigen::VectorXd::Ones(p.size()) -
                ((T - S1) * h / std::pow(S2, 1.5)) * p;
  return q;
}
}  // namespace

double PaperQuadraticBar1D::equilibrium_elastic_energy(const Eigen::VectorXd& p) const {
  const double q = elastic_residual(*this, p, nullptr);
  return q * q;
}

Eigen::VectorXd PaperQuadraticBar1D::equilibrium_elastic_gradient(const Eigen::VectorXd& p) const {
  Eigen::VectorXd dq;
  const double q = elastic_residual(*this, p, &dq);
  return 2.0 * q * dq;
}

Eigen::VectorXd PaperQuadraticBar1D::residuals(const Eigen::VectorXd& p, double alpha, double beta,
                                               Smoothness1DOrder order) const {
  const Eigen::MatrixXd& W = order == Smoothness1DOrder::kFirst ? w_first_ : w_second_;
  const int q = static_cast<int>(landmark_nodes_.size());
  Eigen::VectorXd r(W.rows() + q + 1);
  r.head(W.rows()) = W * p;
  const Eigen::VectorXd x = positions(p);
  for (int l = 0; l < q; ++l)
    r[W.rows() + l] = std::sqrt(alpha) * (x[landmark_nodes_[l]] - setup_.landmark_target[l]);
  r[W.rows() + q] = std::sqrt(beta) * elastic_residual(*this, p, nullptr);
  return r;
}

Eigen::MatrixXd PaperQuadraticBar1D::residual_jacobian(const Eigen::VectorXd& p, double alpha,
                                                       double beta, Smoothness1DOrder order) const {
  const Eigen::MatrixXd& W = order == Smoothness1DOrder::kFirst ? w_first_ : w_second_;
  const int q = static_cast<int>(landmark_nodes_.size());
  Eigen::MatrixXd Jr(W.rows() + q + 1, n_);
  Jr.topRows(W.rows()) = W;
  const Eigen::MatrixXd J = positions_jacobian(p);
  for (int l = 0; l < q; ++l) Jr.row(W.rows() + l) = std::sqrt(alpha) * J.row(landmark_nodes_[l]);
  Eigen::VectorXd dq;
  elastic_residual(*this, p, &dq);
  Jr.row(W.rows() + q) = std::sqrt(beta) * dq.transpose();
  return Jr;
}

double PaperQuadraticBar1D::objective(const Eigen::VectorXd& p, double alpha, double beta,
                                      Smoothness1DOrder order) const {
  return residuals(p, alpha, beta, order).squaredNorm();
}

Eigen::VectorXd PaperQuadraticBar1D::objective_gradient(const Eigen::VectorXd& p, double alpha,
                                                        double beta,
                                                        Smoothness1DOrder order) const {
  return 2.0 * residual_jacobian(p, alpha, beta, order).transpose() *
         residuals(p, alpha, beta, order);
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
  else if (model == Plastic1DModel::kPaperQuadratic && !(beta > 0))
    m << "beta = " << beta << " must be > 0 for the paper model (beta = 0 has no minimiser)";
  else if (!(beta >= 0))
    m << "beta = " << beta << " must be >= 0";
  else if (!(gradient_tolerance > 0))
    m << "gradient_tolerance = " << gradient_tolerance << " must be > 0";
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
    << "  final terms: S(p) = " << smoothness_term << ", landmark misfit^2 = " << landmark_term
    << ", E_a = " << attachment_term << ", E = " << elastic_term
    << ", |grad|_inf = " << final_gradient_norm << "\n";
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
  double smoothness = 0, landmark = 0, attachment = 0, max_landmark_error = 0;
};

Terms evaluate_terms(const PlasticBar1D& bar, const Eigen::MatrixXd& L, const Eigen::VectorXd& x,
                     const Eigen::VectorXd& s) {
  Terms t;
  t.smoothness = (L * s).squaredNorm();
  for (size_t l = 0; l < bar.landmark_nodes().size(); ++l) {
    const double r = x[bar.landmark_nodes()[l]] - bar.setup().landmark_target[l];
    t.landmark += r * r;
    t.max_landmark_error = std::max(t.max_landmark_error, std::abs(r));
  }
  t.attachment = bar.attachment_energy(x);
  return t;
}

double objective(const Terms& t, const Plastic1DOptions& o) {
  return t.smoothness + o.alpha * t.landmark + o.beta * t.attachment;
}

/// Eq. 26 by Levenberg–Marquardt on Φ(p) = ‖r(p)‖² with the exact Jacobian (x(p) is explicit).
Plastic1DResult solve_paper_quadratic(const Plastic1DOptions& o, const Plastic1DSetup& setup,
                                      Clock::time_point t0) {
  Plastic1DResult result;
  Plastic1DSummary& sum = result.summary;
  const int n = o.num_elements;
  const PaperQuadraticBar1D bar(n, setup);
  const auto eval = [&](const Eigen::VectorXd& p) {
    return bar.residuals(p, o.alpha, o.beta, o.smoothness);
  };
  result.X = Eigen::VectorXd::LinSpaced(n + 1, 0.0, 1.0);
  Eigen::VectorXd& p = result.s;
  p = Eigen::VectorXd::Ones(n);
  Eigen::VectorXd r = eval(p);
  double phi = r.squaredNorm();
  sum.initial_objective = phi;
  sum.status = Plastic1DStatus::kMaxIterations;
  double lambda = 1e-3;
  Eigen::MatrixXd Jr = bar.residual_jacobian(p, o.alpha, o.beta, o.smoothness);
  for (int it = 0; it < o.max_iterations; ++it) {
    const Eigen::VectorXd half_gradient = Jr.transpose() * r;
    sum.final_gradient_norm = 2.0 * half_gradient.lpNorm<Eigen::Infinity>();
    if (sum.final_gradient_norm <= o.gradient_tolerance * std::max(1.0, phi)) {
      sum.status = Plastic1DStatus::kConverged;
      break;
    }
    ++sum.iterations;
    const Eigen::MatrixXd H = Jr.transpose() * Jr;
    const double floor = 1e-12 * std::max(1.0, H.diagonal().maxCoeff());
    bool accepted = false;
    for (int k = 0; k < 60; ++k) {  // raise the damping until Φ decreases
      Eigen::MatrixXd A = H;
      A.diagonal() += lambda * H.diagonal().cwiseMax(floor);
      const Eigen::VectorXd p_try = p + A.ldlt().solve(-half_gradient);
      const Eigen::VectorXd r_try = eval(p_try);
      const double phi_try = r_try.squaredNorm();
      if (std::isfinite(phi_try) && phi_try < phi) {
        p = p_try;
        r = r_try;
        phi = phi_try;
        accepted = true;
        lambda = std::max(lambda / 3.0, 1e-15);
        break;
      }
      lambda *= 4.0;
    }
    if (!accepted) {  // no damped step decreases Φ: round-off level when the gradient is small
      sum.status = sum.final_gradient_norm <= 100.0 * o.gradient_tolerance * std::max(1.0, phi)
                       ? Plastic1DStatus::kConverged
                       : Plastic1DStatus::kLineSearchFailed;
      break;
    }
    Jr = bar.residual_jacobian(p, o.alpha, o.beta, o.smoothness);
  }
  result.x = bar.positions(p);
  const Eigen::MatrixXd W = smoothness_matrix(n, o.smoothness);
  sum.final_objective = phi;
  sum.smoothness_term = (W * p).squaredNorm();
  sum.elastic_term = bar.equilibrium_elastic_energy(p);
  for (size_t l = 0; l < bar.landmark_nodes().size(); ++l) {
    const double e = result.x[bar.landmark_nodes()[l]] - setup.landmark_target[l];
    sum.landmark_term += e * e;
    sum.max_landmark_error = std::max(sum.max_landmark_error, std::abs(e));
  }
  sum.seconds = seconds_since(t0);
  return result;
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
  if (o.model == Plastic1DModel::kPaperQuadratic) {
    if (auto msg = paper_setup_error(setup)) {
      sum.message = *msg;
      return result;
    }
    return solve_paper_quadratic(o, setup, t0);
  }
  const int n = o.num_elements;
  const PlasticBar1D bar(n, o.psi, o.attachment_stiffness, setup);
  const Eigen::MatrixXd L = smoothness_matrix(n, o.smoothness);
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
  sum.smoothness_term = terms.smoothness;
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

// ---------------------------------------------------------------------------------------------
// Fig. 23 metrics and the comparison table.

double Fig23Metrics::max_relative_fitted_slope_error() const {
  double e = 0.0;
  for (size_t k = 0; k < fitted_slope.size(); ++k)
    e = std::max(e, std::abs(fitted_slope[k] / target_slope[k] - 1.0));
  return e;
}

Fig23Metrics measure_fig23(const Eigen::VectorXd& X, const Eigen::VectorXd& x,
                           const Plastic1DSetup& setup, double margin) {
  Fig23Metrics m;
  const int n = static_cast<int>(X.size()) - 1;
  std::vector<std::pair<double, double>> points;  // (material X, target position)
  for (size_t a = 0; a < setup.attachment_X.size(); ++a)
    points.emplace_back(setup.attachment_X[a], setup.attachment_target[a]);
  for (size_t l = 0; l < setup.landmark_X.size(); ++l)
    points.emplace_back(setup.landmark_X[l], setup.landmark_target[l]);
  std::sort(points.begin(), points.end());
  for (size_t k = 0; k < points.size(); ++k) {
    m.bounds.push_back(points[k].first);
    if (k == 0) continue;
    const double a = points[k - 1].first, b = points[k].first;
    const int ia = nearest_node(a, n), ib = nearest_node(b, n);
    m.target_slope.push_back((points[k].second - points[k - 1].second) / (b - a));
    m.chord_slope.push_back((x[ib] - x[ia]) / (X[ib] - X[ia]));
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    int count = 0;
    for (int i = ia; i <= ib; ++i) {
      if (X[i] < a + margin - 1e-12 || X[i] > b - margin + 1e-12) continue;
      sx += X[i];
      sy += x[i];
      sxx += X[i] * X[i];
      sxy += X[i] * x[i];
      ++count;
    }
    m.fitted_slope.push_back((count * sxy - sx * sy) / (count * sxx - sx * sx));
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (int e = ia; e < ib; ++e) {
      const double slope = (x[e + 1] - x[e]) / (X[e + 1] - X[e]);
      lo = std::min(lo, slope);
      hi = std::max(hi, slope);
    }
    m.min_local_slope.push_back(lo);
    m.max_local_slope.push_back(hi);
  }
  for (size_t l = 0; l < setup.landmark_X.size(); ++l)
    m.max_landmark_error =
        std::max(m.max_landmark_error,
                 std::abs(x[nearest_node(setup.landmark_X[l], n)] - setup.landmark_target[l]));
  m.min_x = x.minCoeff();
  m.max_x = x.maxCoeff();
  m.monotone = true;
  for (int e = 0; e < n; ++e) m.monotone = m.monotone && x[e + 1] >= x[e];
  const auto [t_lo, t_hi] =
      std::minmax_element(setup.attachment_target.begin(), setup.attachment_target.end());
  m.overshoot = std::max({0.0, *t_lo - m.min_x, m.max_x - *t_hi});
  return m;
}

std::vector<Fig23Row> fig23_table(const Plastic1DOptions& options,
                                  const std::vector<double>& alphas,
                                  const std::vector<double>& betas,
                                  const std::vector<int>& element_counts, double margin) {
  const Plastic1DSetup setup{};
  std::vector<Fig23Row> rows;
  for (int n : element_counts) {
    const Eigen::VectorXd X = Eigen::VectorXd::LinSpaced(n + 1, 0.0, 1.0);
    for (double beta : betas)
      for (double alpha : alphas) {
        Plastic1DOptions o = options;
        o.num_elements = n;
        o.alpha = alpha;
        o.beta = beta;
        const Plastic1DResult r = solve_plastic_1d(o, setup);
        Fig23Row row{"plastic", 0, alpha, beta, n, to_string(r.summary.status), 0.0, 0.0, {}};
        if (r.x.size() == n + 1) {
          row.min_fp = r.s.minCoeff();
          row.max_fp = r.s.maxCoeff();
          row.metrics = measure_fig23(X, r.x, setup, margin);
        }
        rows.push_back(row);
      }
    for (int order = 1; order <= 3; ++order)
      for (double alpha : alphas) {
        Variational1DOptions vo;
        vo.num_elements = n;
        vo.order = order;
        vo.alpha = alpha;
        const auto x = solve_variational_1d(vo, setup);
        Fig23Row row{"variational r=" + std::to_string(order), order, alpha, 0.0, n,
                     x ? "solved" : "invalid options",         0.0,   0.0,   {}};
        if (x) row.metrics = measure_fig23(X, *x, setup, margin);
        rows.push_back(row);
      }
  }
  return rows;
}

std::string format_fig23_table(const std::vector<Fig23Row>& rows) {
  std::ostringstream o;
  char line[512];
  std::snprintf(line, sizeof line, "%-16s %7s %7s %4s | %-20s | %-20s | %-38s | %8s %4s %7s %s\n",
                "method", "alpha", "beta", "N", "chord slopes", "fitted slopes",
                "local slope range per subinterval", "lm err", "mono", "oversh", "status");
  o << line;
  for (const Fig23Row& r : rows) {
    const Fig23Metrics& m = r.metrics;
    if (m.fitted_slope.size() != 3) {
      o << r.method << " alpha " << r.alpha << " beta " << r.beta << " N " << r.num_elements << ": "
        << r.status << "\n";
      continue;
    }
    std::snprintf(line, sizeof line,
                  "%-16s %7.0e %7.0e %4d | %6.3f %6.3f %6.3f | %6.3f %6.3f %6.3f | "
                  "[%5.2f,%5.2f] [%5.2f,%5.2f] [%5.2f,%5.2f] | %8.1e %4s %7.4f %s",
                  r.method.c_str(), r.alpha, r.beta, r.num_elements, m.chord_slope[0],
                  m.chord_slope[1], m.chord_slope[2], m.fitted_slope[0], m.fitted_slope[1],
                  m.fitted_slope[2], m.min_local_slope[0], m.max_local_slope[0],
                  m.min_local_slope[1], m.max_local_slope[1], m.min_local_slope[2],
                  m.max_local_slope[2], m.max_landmark_error, m.monotone ? "yes" : "no",
                  m.overshoot, r.status.c_str());
    o << line;
    if (r.order == 0) {
      std::snprintf(line, sizeof line, " fp[%.3f,%.3f]", r.min_fp, r.max_fp);
      o << line;
    }
    o << "\n";
  }
  return o.str();
}

}  // namespace sinew::offline::experiments
