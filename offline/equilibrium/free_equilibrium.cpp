#include "offline/equilibrium/free_equilibrium.hpp"

#include <IpIpoptApplication.hpp>
#include <IpSolveStatistics.hpp>
#include <IpTNLP.hpp>
#include <chrono>
#include <cmath>

#include "offline/detail/ipopt_capture.hpp"
#include "offline/detail/ipopt_problem.hpp"

namespace sinew::offline {
namespace {

using Clock = std::chrono::steady_clock;

// Eqs. 18–20 as an Ipopt NLP. Hessian entries: K's upper triangle (as Ipopt's lower triangle),
// then the lower triangle of the dense stabilisation block over the support dofs (duplicates of
// K's positions are summed by Ipopt).
class FreeEquilibriumProblem : public detail::UnboundedIpoptProblem {
 public:
  FreeEquilibriumProblem(PlasticElasticEnergy& energy, const RigidStabilisation& stabilisation,
                         const RigidFrame& frame, const Eigen::Ref<const Eigen::VectorXd>& s,
                         const Eigen::VectorXd& x0)
      : UnboundedIpoptProblem(x0),
        energy_(energy),
        stabilisation_(stabilisation),
        frame_(frame),
        s_(s),
        x_start_(x0) {
    for (Eigen::Index v : stabilisation.support_vertices()) {
      for (int c = 0; c < 3; ++c) support_dofs_.push_back(3 * v + c);
    }
  }

  bool get_nlp_info(Ipopt::Index& n, Ipopt::Index& m, Ipopt::Index& nnz_jac_g,
                    Ipopt::Index& nnz_h_lag, IndexStyleEnum& index_style) override {
    const auto d = static_cast<Ipopt::Index>(support_dofs_.size());
    n = static_cast<Ipopt::Index>(energy_.num_dofs());
    m = 6;
    nnz_jac_g = 6 * d;
    nnz_h_lag = static_cast<Ipopt::Index>(energy_.stiffness().nonZeros()) + d * (d + 1) / 2;
    index_style = C_STYLE;
    return true;
  }

  bool eval_f(Ipopt::Index n, const Ipopt::Number* x, bool, Ipopt::Number& value) override {
    PlasticEnergyRequest request;
    if (!energy_.evaluate(s_, Eigen::Map<const Eigen::VectorXd>(x, n), request).valid())
      return false;
    value = energy_.energy();
    return std::isfinite(value);
  }

  bool eval_grad_f(Ipopt::Index n, const Ipopt::Number* x, bool, Ipopt::Number* grad) override {
    PlasticEnergyRequest request;
    request.energy = false;
    request.gradient_x = true;
    if (!energy_.evaluate(s_, Eigen::Map<const Eigen::VectorXd>(x, n), request).valid())
      return false;
    Eigen::Map<Eigen::VectorXd>(grad, n) = energy_.gradient_x();
    return true;
  }

  bool eval_g(Ipopt::Index n, const Ipopt::Number* x, bool, Ipopt::Index,
              Ipopt::Number* g) override {
    const auto r = stabilisation_.residual(Eigen::Map<const Eigen::VectorXd>(x, n), frame_);
    if (!r) return false;
    Eigen::Map<Vector6d> out(g);
    out = *r;
    return true;
  }

  bool eval_jac_g(Ipopt::Index n, const Ipopt::Number* x, bool, Ipopt::Index, Ipopt::Index,
                  Ipopt::Index* iRow, Ipopt::Index* jCol, Ipopt::Number* values) override {
    const auto d = support_dofs_.size();
    if (values == nullptr) {
      for (int i = 0; i < 6; ++i) {
        for (std::size_t k = 0; k < d; ++k) {
          iRow[static_cast<std::size_t>(i) * d + k] = i;
          jCol[static_cast<std::size_t>(i) * d + k] = static_cast<Ipopt::Index>(support_dofs_[k]);
        }
      }
      return true;
    }
    StabilisationJacobian G;
    if (!stabilisation_.jacobian(Eigen::Map<const Eigen::VectorXd>(x, n), frame_, G)) return false;
    for (int i = 0; i < 6; ++i) {
      for (std::size_t k = 0; k < d; ++k) {
        values[static_cast<std::size_t>(i) * d + k] = G(i, support_dofs_[k]);
      }
    }
    return true;
  }

  bool eval_h(Ipopt::Index n, const Ipopt::Number* x, bool, Ipopt::Number obj_factor, Ipopt::Index,
              const Ipopt::Number* lambda, bool, Ipopt::Index, Ipopt::Index* iRow,
              Ipopt::Index* jCol, Ipopt::Number* values) override {
    const Eigen::SparseMatrix<double>& K = energy_.stiffness();
    const auto d = static_cast<Eigen::Index>(support_dofs_.size());
    Ipopt::Index k = 0;
    if (values == nullptr) {
      for (Eigen::Index c = 0; c < K.outerSize(); ++c) {
        for (Eigen::SparseMatrix<double>::InnerIterator it(K, c); it; ++it, ++k) {
          iRow[k] = static_cast<Ipopt::Index>(it.col());  // upper (r ≤ c) → lower
          jCol[k] = static_cast<Ipopt::Index>(it.row());
        }
      }
      for (Eigen::Index a = 0; a < d; ++a) {
        for (Eigen::Index b = 0; b <= a; ++b, ++k) {
          iRow[k] = static_cast<Ipopt::Index>(support_dofs_[static_cast<std::size_t>(a)]);
          jCol[k] = static_cast<Ipopt::Index>(support_dofs_[static_cast<std::size_t>(b)]);
        }
      }
      return true;
    }
    const Eigen::Map<const Eigen::VectorXd> xv(x, n);
    PlasticEnergyRequest request;
    request.energy = false;
    request.stiffness = true;
    if (!energy_.evaluate(s_, xv, request).valid()) return false;
    for (Eigen::Index i = 0; i < K.nonZeros(); ++i, ++k) values[k] = obj_factor * K.valuePtr()[i];
    Eigen::MatrixXd H;
    if (!stabilisation_.hessian(xv, frame_, Eigen::Map<const Vector6d>(lambda), H)) return false;
    for (Eigen::Index a = 0; a < d; ++a) {
      for (Eigen::Index b = 0; b <= a; ++b, ++k) values[k] = H(a, b);
    }
    return true;
  }

 protected:
  Eigen::Ref<const Eigen::VectorXd> start() const override { return x_start_; }

 private:
  PlasticElasticEnergy& energy_;
  const RigidStabilisation& stabilisation_;
  RigidFrame frame_;
  Eigen::Ref<const Eigen::VectorXd> s_;
  Eigen::VectorXd x_start_;
  std::vector<Eigen::Index> support_dofs_;
};

}  // namespace

FreeEquilibriumSummary solve_free_equilibrium(const PlasticElasticEnergy& energy_in,
                                              const RigidStabilisation& stabilisation,
                                              const RigidFrame& frame,
                                              const Eigen::Ref<const Eigen::VectorXd>& s,
                                              Eigen::Ref<Eigen::VectorXd> x,
                                              const FreeEquilibriumOptions& options) {
  const Clock::time_point start = Clock::now();
  FreeEquilibriumSummary summary;
  if (x.size() != energy_in.num_dofs() || s.size() != energy_in.num_plastic_dofs() ||
      stabilisation.num_dofs() != energy_in.num_dofs()) {
    return summary;
  }
  PlasticElasticEnergyOptions upper = energy_in.options();
  upper.storage = common::PatternStorage::kUpper;
  upper.projection = common::HessianProjection::kNone;
  auto energy = PlasticElasticEnergy::create(common::to_positions(energy_in.rest_dofs()),
                                             energy_in.tets(), energy_in.material(), upper);
  if (!energy) return summary;
  double volume = 0.0;
  for (const common::Tet4Rest& r : energy->rest()) volume += std::abs(r.volume);
  const double h = std::cbrt(volume / static_cast<double>(energy->num_tets()));
  summary.force_scale = energy->material().mu() * h * h;

  Ipopt::SmartPtr<Ipopt::IpoptApplication> app = new Ipopt::IpoptApplication();
  Ipopt::SmartPtr<FreeEquilibriumProblem> problem =
      new FreeEquilibriumProblem(*energy, stabilisation, frame, s, Eigen::VectorXd(x));
  {
    Ipopt::SmartPtr<Ipopt::OptionsList> o = app->Options();
    o->SetIntegerValue("print_level", options.print_level);
    o->SetStringValue("sb", "yes");
    o->SetIntegerValue("max_iter", options.max_iterations);
    o->SetStringValue("nlp_scaling_method", "none");
    o->SetNumericValue("obj_scaling_factor", 1.0 / summary.force_scale);
    o->SetNumericValue("tol", options.force_tolerance);
    o->SetNumericValue("constr_viol_tol", options.constraint_tolerance);
    o->SetStringValue("hessian_approximation", "exact");
  }
  const detail::IpoptRun run =
      detail::run_ipopt(*app, Ipopt::GetRawPtr(problem), options.derivative_test,
                        options.derivative_test_tolerance, options.derivative_test_perturbation);
  const Ipopt::ApplicationReturnStatus status = run.status;
  summary.ipopt_return_code = static_cast<int>(status);
  summary.derivative_test_errors = run.derivative_test_errors;
  if (run.iterations) summary.iterations = *run.iterations;
  x = problem->x_final();

  PlasticEnergyRequest request;
  request.energy = false;
  request.gradient_x = true;
  const bool evaluated = energy->evaluate(s, x, request).valid();
  const auto g = stabilisation.residual(x, frame);
  summary.residual_norm = evaluated ? energy->gradient_x().lpNorm<Eigen::Infinity>() : INFINITY;
  summary.constraint_violation = g ? g->lpNorm<Eigen::Infinity>() : INFINITY;
  if (summary.residual_norm <= options.force_tolerance * summary.force_scale &&
      summary.constraint_violation <= options.constraint_tolerance) {
    summary.status = EquilibriumStatus::kConverged;
  } else if (status == Ipopt::Maximum_Iterations_Exceeded) {
    summary.status = EquilibriumStatus::kMaxIterations;
  } else if (!evaluated || !g) {
    summary.status = EquilibriumStatus::kNonFinite;
  } else {
    summary.status = EquilibriumStatus::kIpoptFailed;
  }
  summary.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return summary;
}

}  // namespace sinew::offline
