#include "offline/equilibrium/equilibrium.hpp"

#include "offline/detail/ipopt_capture.hpp"
#include "offline/detail/ipopt_problem.hpp"
#include "offline/rigid/rigid_motion.hpp"

#include <IpIpoptApplication.hpp>
#include <IpJournalist.hpp>
#include <IpSolveStatistics.hpp>
#include <IpTNLP.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <limits>
#include <sstream>

#include "common/detail/field_error.hpp"
#include "common/fem/sparse_assembly.hpp"
#include "common/fem/tet4.hpp"
#include "common/timing.hpp"

namespace sinew::offline {
namespace {

using Clock = std::chrono::steady_clock;

using common::seconds_since;

// Relative slack of the Armijo test for round-off in Π (a sum over thousands of tets): near the
// solution the decrease c₁α∇ΠᵀΔx drops below what the energy can resolve.
constexpr double kEnergyRoundoff = 1e-12;

std::string field_error(const char* field, double value, const char* constraint) {
  return common::detail::field_error("EquilibriumOptions::", field, value,
                                     std::string("must be ") + constraint);
}

const char* ipopt_status_name(int code) {
  switch (static_cast<Ipopt::ApplicationReturnStatus>(code)) {
    case Ipopt::Solve_Succeeded:
      return "Solve_Succeeded";
    case Ipopt::Solved_To_Acceptable_Level:
      return "Solved_To_Acceptable_Level";
    case Ipopt::Infeasible_Problem_Detected:
      return "Infeasible_Problem_Detected";
    case Ipopt::Search_Direction_Becomes_Too_Small:
      return "Search_Direction_Becomes_Too_Small";
    case Ipopt::Diverging_Iterates:
      return "Diverging_Iterates";
    case Ipopt::User_Requested_Stop:
      return "User_Requested_Stop";
    case Ipopt::Feasible_Point_Found:
      return "Feasible_Point_Found";
    case Ipopt::Maximum_Iterations_Exceeded:
      return "Maximum_Iterations_Exceeded";
    case Ipopt::Restoration_Failed:
      return "Restoration_Failed";
    case Ipopt::Error_In_Step_Computation:
      return "Error_In_Step_Computation";
    case Ipopt::Maximum_CpuTime_Exceeded:
      return "Maximum_CpuTime_Exceeded";
    case Ipopt::Not_Enough_Degrees_Of_Freedom:
      return "Not_Enough_Degrees_Of_Freedom";
    case Ipopt::Invalid_Problem_Definition:
      return "Invalid_Problem_Definition";
    case Ipopt::Invalid_Option:
      return "Invalid_Option";
    case Ipopt::Invalid_Number_Detected:
      return "Invalid_Number_Detected";
    case Ipopt::Unrecoverable_Exception:
      return "Unrecoverable_Exception";
    case Ipopt::NonIpopt_Exception_Thrown:
      return "NonIpopt_Exception_Thrown";
    case Ipopt::Insufficient_Memory:
      return "Insufficient_Memory";
    case Ipopt::Internal_Error:
      return "Internal_Error";
  }
  return "unknown";
}

}  // namespace

const char* to_string(EquilibriumMethod method) {
  switch (method) {
    case EquilibriumMethod::kNewton:
      return "newton";
    case EquilibriumMethod::kIpopt:
      return "ipopt";
  }
  return "unknown";
}

const char* to_string(StiffnessProjection projection) {
  switch (projection) {
    case StiffnessProjection::kNever:
      return "never";
    case StiffnessProjection::kOnFailure:
      return "on-failure";
    case StiffnessProjection::kAlways:
      return "always";
  }
  return "unknown";
}

const char* to_string(EquilibriumStatus status) {
  switch (status) {
    case EquilibriumStatus::kConverged:
      return "converged";
    case EquilibriumStatus::kMaxIterations:
      return "max iterations";
    case EquilibriumStatus::kLineSearchFailed:
      return "line search failed";
    case EquilibriumStatus::kNotPositiveDefinite:
      return "stiffness not positive definite";
    case EquilibriumStatus::kIpoptFailed:
      return "ipopt failed";
    case EquilibriumStatus::kNonFinite:
      return "non-finite";
    case EquilibriumStatus::kInvalidInput:
      return "invalid input";
  }
  return "unknown";
}

std::optional<std::string> EquilibriumOptions::validate() const {
  if (max_iterations < 0) return field_error("max_iterations", max_iterations, ">= 0");
  if (!(force_tolerance > 0.0 && force_tolerance < 1.0)) {
    return field_error("force_tolerance", force_tolerance, "in (0, 1)");
  }
  if (projection == common::HessianProjection::kNone) {
    return std::string(
        "EquilibriumOptions::projection = kNone: must be kProjectElement or kProjectDPdF");
  }
  if (!(armijo_parameter > 0.0 && armijo_parameter < 0.5)) {
    return field_error("armijo_parameter", armijo_parameter, "in (0, 0.5)");
  }
  if (!(backtracking_factor > 0.0 && backtracking_factor < 1.0)) {
    return field_error("backtracking_factor", backtracking_factor, "in (0, 1)");
  }
  if (max_line_search_steps < 1) {
    return field_error("max_line_search_steps", max_line_search_steps, ">= 1");
  }
  if (ipopt_print_level < 0 || ipopt_print_level > 12) {
    return field_error("ipopt_print_level", ipopt_print_level, "in [0, 12]");
  }
  if (!(ipopt_derivative_test_tolerance > 0.0 && ipopt_derivative_test_tolerance < 1.0)) {
    return field_error("ipopt_derivative_test_tolerance", ipopt_derivative_test_tolerance,
                       "in (0, 1)");
  }
  if (!(ipopt_derivative_test_perturbation > 0.0 && ipopt_derivative_test_perturbation < 0.1)) {
    return field_error("ipopt_derivative_test_perturbation", ipopt_derivative_test_perturbation,
                       "in (0, 0.1)");
  }
  return std::nullopt;
}

std::string EquilibriumSummary::brief_report() const {
  std::ostringstream s;
  s << "Equilibrium (" << to_string(method) << "): " << to_string(status) << ", " << iterations
    << " iterations, |f_net|inf ";
  if (residual_norm) {
    s << *residual_norm << " N (scale " << force_scale << " N)";
  } else {
    s << "not evaluated";
  }
  s << ", " << seconds << " s";
  return s.str();
}

std::string EquilibriumSummary::full_report() const {
  std::ostringstream s;
  s << "Equilibrium solve\n"
    << "  method:                   " << to_string(method) << "\n"
    << "  status:                   " << to_string(status) << "\n"
    << "  iterations:               " << iterations << "\n";
  s << "  initial |f_net|inf (N):   ";
  if (initial_residual_norm) {
    s << *initial_residual_norm << "\n";
  } else {
    s << "not evaluated\n";
  }
  s << "  final |f_net|inf (N):     ";
  if (residual_norm) {
    s << *residual_norm << "\n";
  } else {
    s << "not evaluated\n";
  }
  s << "  force scale (N):          " << force_scale << "\n";
  s << "  energy (J):               ";
  if (energy) {
    s << *energy << "\n";
  } else {
    s << "not evaluated\n";
  }
  s << "  factorisations:           " << factorisations << " (" << projected_factorisations
    << " projected)\n"
    << "  energy evaluations:       " << energy_evaluations << "\n"
    << "  rejected inversions:      " << rejected_inversions << "\n";
  if (ipopt_return_code) {
    s << "  ipopt return status:      " << ipopt_status_name(*ipopt_return_code) << " ("
      << *ipopt_return_code << ")\n";
  }
  if (derivative_test_errors) {
    s << "  derivative test errors:   " << *derivative_test_errors << "\n";
  }
  s << "  time (s):                 " << seconds << " (factorisation " << factorisation_seconds
    << ", assembly " << assembly_seconds << ")\n";
  return s.str();
}

// ---------------------------------------------------------------------------------------------
// Ipopt adapter: min Π(x), no constraints, exact gradient and Hessian (lower triangle of K_total).

namespace detail {

class EquilibriumIpoptProblem : public UnboundedIpoptProblem {
 public:
  EquilibriumIpoptProblem(EquilibriumSolver* solver, const Eigen::Ref<const Eigen::VectorXd>* s,
                          const Eigen::Ref<const Eigen::VectorXd>* x0)
      : UnboundedIpoptProblem(*x0), solver_(solver), s_(s), x0_(x0) {}

  bool get_nlp_info(Ipopt::Index& n, Ipopt::Index& m, Ipopt::Index& nnz_jac_g,
                    Ipopt::Index& nnz_h_lag, IndexStyleEnum& index_style) override {
    n = static_cast<Ipopt::Index>(solver_->num_dofs_);
    m = 0;
    nnz_jac_g = 0;
    nnz_h_lag = static_cast<Ipopt::Index>(solver_->total_.nonZeros());
    index_style = C_STYLE;
    return true;
  }

  bool eval_f(Ipopt::Index n, const Ipopt::Number* x, bool, Ipopt::Number& obj_value) override {
    const Eigen::Map<const Eigen::VectorXd> xv(x, n);
    const std::optional<double> e = solver_->total_energy(*s_, xv);
    if (!e) return false;
    obj_value = *e;
    return true;
  }

  bool eval_grad_f(Ipopt::Index n, const Ipopt::Number* x, bool, Ipopt::Number* grad_f) override {
    const Eigen::Map<const Eigen::VectorXd> xv(x, n);
    double e = 0.0;
    if (!solver_->energy_and_gradient(*s_, xv, &e)) return false;
    Eigen::Map<Eigen::VectorXd>(grad_f, n) = solver_->gradient_;
    return true;
  }

  bool eval_g(Ipopt::Index, const Ipopt::Number*, bool, Ipopt::Index, Ipopt::Number*) override {
    return true;
  }

  bool eval_jac_g(Ipopt::Index, const Ipopt::Number*, bool, Ipopt::Index, Ipopt::Index,
                  Ipopt::Index*, Ipopt::Index*, Ipopt::Number*) override {
    return true;
  }

  bool eval_h(Ipopt::Index n, const Ipopt::Number* x, bool, Ipopt::Number obj_factor, Ipopt::Index,
              const Ipopt::Number*, bool, Ipopt::Index nele_hess, Ipopt::Index* iRow,
              Ipopt::Index* jCol, Ipopt::Number* values) override {
    const Eigen::SparseMatrix<double>& K = solver_->total_;
    if (nele_hess != K.nonZeros()) return false;
    if (values == nullptr) {
      // Structure: K_total's upper triangle (r ≤ c) is the lower triangle of its transpose.
      Ipopt::Index k = 0;
      for (Eigen::Index c = 0; c < K.outerSize(); ++c) {
        for (Eigen::SparseMatrix<double>::InnerIterator it(K, c); it; ++it, ++k) {
          iRow[k] = static_cast<Ipopt::Index>(it.col());
          jCol[k] = static_cast<Ipopt::Index>(it.row());
        }
      }
      return true;
    }
    const Eigen::Map<const Eigen::VectorXd> xv(x, n);
    const bool projected = solver_->options_.stiffness_projection == StiffnessProjection::kAlways;
    if (!solver_->assemble_total_stiffness(*s_, xv, projected)) return false;
    Eigen::Map<Eigen::VectorXd>(values, nele_hess) =
        obj_factor * Eigen::Map<const Eigen::VectorXd>(K.valuePtr(), nele_hess);
    return true;
  }

 protected:
  Eigen::Ref<const Eigen::VectorXd> start() const override { return *x0_; }

 private:
  EquilibriumSolver* solver_;
  const Eigen::Ref<const Eigen::VectorXd>* s_;
  const Eigen::Ref<const Eigen::VectorXd>* x0_;
};

}  // namespace detail

// ---------------------------------------------------------------------------------------------

EquilibriumSolver::EquilibriumSolver(const EquilibriumOptions& options,
                                     const PointConstraints& attachments,
                                     PlasticElasticEnergy exact)
    : options_(options),
      attachments_(&attachments),
      num_dofs_(exact.num_dofs()),
      exact_(std::move(exact)),
      cholesky_(SparseCholeskyOptions{options.ordering, options.cholesky_method}) {}

EquilibriumSolver::EquilibriumSolver(EquilibriumSolver&&) noexcept = default;
EquilibriumSolver& EquilibriumSolver::operator=(EquilibriumSolver&&) noexcept = default;
EquilibriumSolver::~EquilibriumSolver() = default;

std::optional<EquilibriumSolver> EquilibriumSolver::create(const PlasticElasticEnergy& energy,
                                                           const PointConstraints& attachments,
                                                           const EquilibriumOptions& options,
                                                           std::string* error) {
  const auto fail = [&](const std::string& message) -> std::optional<EquilibriumSolver> {
    if (error != nullptr) *error = message;
    return std::nullopt;
  };
  if (const auto message = options.validate()) return fail(*message);
  if (attachments.num_dofs() != energy.num_dofs()) {
    std::ostringstream s;
    s << "attachments have " << attachments.num_dofs() << " dofs, the energy " << energy.num_dofs();
    return fail(s.str());
  }
  if (energy.num_tets() == 0) return fail("the energy's mesh has no tets");

  // The solver's own energies: upper-triangle storage for CHOLMOD, exact and projected.
  PlasticElasticEnergyOptions energy_options = energy.options();
  energy_options.storage = common::PatternStorage::kUpper;
  energy_options.projection = common::HessianProjection::kNone;
  const Eigen::MatrixXd rest = common::to_positions(energy.rest_dofs());
  std::optional<PlasticElasticEnergy> exact =
      PlasticElasticEnergy::create(rest, energy.tets(), energy.material(), energy_options);
  if (!exact) return fail("could not rebuild the plastic elastic energy (upper storage)");

  EquilibriumSolver solver(options, attachments, std::move(*exact));
  solver.free_object_ = attachments.size() == 0;
  if (solver.free_object_ && options.method != EquilibriumMethod::kNewton) {
    return fail(
        "a free object (no attachments) needs the Newton back end here; the stabilised Ipopt "
        "problem of eqs. 18-20 is in offline/equilibrium/free_equilibrium.hpp");
  }
  const bool need_projected = options.stiffness_projection == StiffnessProjection::kAlways ||
                              (options.method == EquilibriumMethod::kNewton &&
                               options.stiffness_projection == StiffnessProjection::kOnFailure);
  if (need_projected) {
    energy_options.projection = options.projection;
    solver.projected_ =
        PlasticElasticEnergy::create(rest, energy.tets(), energy.material(), energy_options);
    if (!solver.projected_) return fail("could not build the projected plastic elastic energy");
    if (solver.projected_->stiffness().nonZeros() != solver.exact_.stiffness().nonZeros()) {
      return fail("projected and exact stiffness patterns differ");
    }
  }

  // Pattern of K_total: union of K's upper triangle and H_a's entries with row ≤ column.
  const Eigen::SparseMatrix<double>& K = solver.exact_.stiffness();
  const Eigen::SparseMatrix<double>& Ha = attachments.hessian();
  const Eigen::Index n = solver.num_dofs_;
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<std::size_t>(K.nonZeros() + Ha.nonZeros()));
  for (Eigen::Index c = 0; c < n; ++c) {
    for (Eigen::SparseMatrix<double>::InnerIterator it(K, c); it; ++it) {
      if (it.row() <= c) triplets.emplace_back(it.row(), c, 0.0);
    }
    for (Eigen::SparseMatrix<double>::InnerIterator it(Ha, c); it; ++it) {
      if (it.row() <= c) triplets.emplace_back(it.row(), c, 0.0);
    }
  }
  solver.total_.resize(n, n);
  solver.total_.setFromTriplets(triplets.begin(), triplets.end());
  solver.total_.makeCompressed();
  const Eigen::SparseMatrix<double>& T = solver.total_;
  const auto build_map = [&](const Eigen::SparseMatrix<double>& source,
                             std::vector<std::pair<int, int>>& map) {
    map.clear();
    for (Eigen::Index c = 0; c < n; ++c) {
      const int* begin = T.innerIndexPtr() + T.outerIndexPtr()[c];
      const int* end = T.innerIndexPtr() + T.outerIndexPtr()[c + 1];
      for (Eigen::Index k = source.outerIndexPtr()[c]; k < source.outerIndexPtr()[c + 1]; ++k) {
        const int r = source.innerIndexPtr()[k];
        if (r > c) continue;
        const int* at = std::lower_bound(begin, end, r);
        map.emplace_back(static_cast<int>(k), static_cast<int>(at - T.innerIndexPtr()));
      }
    }
  };
  if (!K.isCompressed() || !Ha.isCompressed()) return fail("stiffness patterns not compressed");
  build_map(K, solver.stiffness_map_);
  build_map(Ha, solver.attachment_map_);

  if (options.method == EquilibriumMethod::kNewton) {
    const SparseCholeskyStatus status = solver.cholesky_.analyse(solver.total_);
    if (status != SparseCholeskyStatus::kOk) {
      return fail(std::string("CHOLMOD analysis of K_total failed: ") + to_string(status));
    }
  }

  double volume = 0.0;
  for (const common::Tet4Rest& r : solver.exact_.rest()) volume += std::abs(r.volume);
  const double h = std::cbrt(volume / static_cast<double>(solver.exact_.num_tets()));
  solver.elastic_force_scale_ = energy.material().mu() * h * h;

  solver.inverted_at_start_.assign(static_cast<std::size_t>(solver.exact_.num_tets()), 0);
  solver.gradient_.setZero(n);
  solver.attachment_gradient_.setZero(n);
  solver.step_.setZero(n);
  solver.trial_.setZero(n);
  return solver;
}

void EquilibriumSolver::record_inversions(const Eigen::Ref<const Eigen::VectorXd>& x) {
  const std::vector<common::Tet4Rest>& rest = exact_.rest();
  for (Eigen::Index t = 0; t < exact_.num_tets(); ++t) {
    const double v = common::signed_volume(exact_.tet_positions(t, x));
    inverted_at_start_[static_cast<std::size_t>(t)] =
        (v * rest[static_cast<std::size_t>(t)].volume <= 0.0) ? 1 : 0;
  }
}

bool EquilibriumSolver::inverts_new_tet(const Eigen::Ref<const Eigen::VectorXd>& x) const {
  const std::vector<common::Tet4Rest>& rest = exact_.rest();
  for (Eigen::Index t = 0; t < exact_.num_tets(); ++t) {
    const auto i = static_cast<std::size_t>(t);
    if (inverted_at_start_[i] != 0) continue;
    if (common::signed_volume(exact_.tet_positions(t, x)) * rest[i].volume <= 0.0) return true;
  }
  return false;
}

std::optional<double> EquilibriumSolver::total_energy(const Eigen::Ref<const Eigen::VectorXd>& s,
                                                      const Eigen::Ref<const Eigen::VectorXd>& x,
                                                      bool* inversion_rejected) {
  const auto start = Clock::now();
  ++energy_evaluations_;
  if (inversion_rejected != nullptr) *inversion_rejected = false;
  if (options_.reject_inversions && inverts_new_tet(x)) {
    ++rejected_inversions_;
    if (inversion_rejected != nullptr) *inversion_rejected = true;
    assembly_seconds_ += seconds_since(start);
    return std::nullopt;
  }
  PlasticEnergyRequest request;
  request.energy = true;
  const PlasticEvaluation evaluation = exact_.evaluate(s, x, request);
  const double e = exact_.energy() + attachments_->energy(x);
  assembly_seconds_ += seconds_since(start);
  if (!evaluation.valid() || !std::isfinite(e)) return std::nullopt;
  return e;
}

bool EquilibriumSolver::energy_and_gradient(const Eigen::Ref<const Eigen::VectorXd>& s,
                                            const Eigen::Ref<const Eigen::VectorXd>& x,
                                            double* energy) {
  const auto start = Clock::now();
  PlasticEnergyRequest request;
  request.energy = true;
  request.gradient_x = true;
  const PlasticEvaluation evaluation = exact_.evaluate(s, x, request);
  if (!evaluation.valid()) {
    assembly_seconds_ += seconds_since(start);
    return false;
  }
  attachments_->gradient(x, attachment_gradient_);
  gradient_ = exact_.gradient_x() + attachment_gradient_;
  *energy = exact_.energy() + attachments_->energy(x);
  last_force_scale_ = std::max({elastic_force_scale_, exact_.gradient_x().lpNorm<Eigen::Infinity>(),
                                attachment_gradient_.lpNorm<Eigen::Infinity>()});
  assembly_seconds_ += seconds_since(start);
  return std::isfinite(*energy) && gradient_.allFinite() && std::isfinite(last_force_scale_);
}

bool EquilibriumSolver::assemble_total_stiffness(const Eigen::Ref<const Eigen::VectorXd>& s,
                                                 const Eigen::Ref<const Eigen::VectorXd>& x,
                                                 bool projected) {
  const auto start = Clock::now();
  PlasticElasticEnergy& energy = (projected && projected_) ? *projected_ : exact_;
  PlasticEnergyRequest request;
  request.energy = false;
  request.stiffness = true;
  const PlasticEvaluation evaluation = energy.evaluate(s, x, request);
  if (!evaluation.valid()) {
    assembly_seconds_ += seconds_since(start);
    return false;
  }
  const double* k = energy.stiffness().valuePtr();
  const double* a = attachments_->hessian().valuePtr();
  double* t = total_.valuePtr();
  std::fill(t, t + total_.nonZeros(), 0.0);
  for (const auto& [src, dst] : stiffness_map_) t[dst] += k[src];
  for (const auto& [src, dst] : attachment_map_) t[dst] += a[src];
  if (pins_) {
    const double diagonal =
        Eigen::Map<const Eigen::VectorXd>(t, total_.nonZeros()).cwiseAbs().maxCoeff();
    pin_dofs(total_, *pins_, diagonal > 0.0 ? diagonal : 1.0);
  }
  assembly_seconds_ += seconds_since(start);
  return Eigen::Map<const Eigen::VectorXd>(t, total_.nonZeros()).allFinite();
}

bool EquilibriumSolver::net_force(const Eigen::Ref<const Eigen::VectorXd>& s,
                                  const Eigen::Ref<const Eigen::VectorXd>& x,
                                  Eigen::Ref<Eigen::VectorXd> net_force) {
  if (s.size() != exact_.num_plastic_dofs() || x.size() != num_dofs_ ||
      net_force.size() != num_dofs_) {
    return false;
  }
  double e = 0.0;
  if (!energy_and_gradient(s, x, &e)) return false;
  net_force = gradient_;
  return true;
}

EquilibriumSummary EquilibriumSolver::solve(const Eigen::Ref<const Eigen::VectorXd>& s,
                                            Eigen::Ref<Eigen::VectorXd> x) {
  const auto start = Clock::now();
  EquilibriumSummary summary;
  summary.method = options_.method;
  energy_evaluations_ = 0;
  rejected_inversions_ = 0;
  assembly_seconds_ = 0.0;
  const double factorisation_seconds_before = cholesky_.total_factorisation_seconds();

  if (s.size() != exact_.num_plastic_dofs() || x.size() != num_dofs_) {
    summary.status = EquilibriumStatus::kInvalidInput;
  } else if (!s.allFinite() || !x.allFinite()) {
    summary.status = EquilibriumStatus::kNonFinite;
  } else {
    record_inversions(x);
    double energy = 0.0;
    if (!energy_and_gradient(s, x, &energy)) {
      summary.status = EquilibriumStatus::kNonFinite;
    } else {
      summary.initial_residual_norm = gradient_.lpNorm<Eigen::Infinity>();
      summary.residual_norm = summary.initial_residual_norm;
      summary.energy = energy;
      summary.force_scale = last_force_scale_;
      summary = options_.method == EquilibriumMethod::kNewton ? solve_newton(s, x, summary)
                                                              : solve_ipopt(s, x, summary);
    }
  }
  summary.energy_evaluations += energy_evaluations_;
  summary.rejected_inversions = rejected_inversions_;
  summary.assembly_seconds = assembly_seconds_;
  summary.factorisation_seconds =
      cholesky_.total_factorisation_seconds() - factorisation_seconds_before;
  summary.seconds = seconds_since(start);
  return summary;
}

EquilibriumSummary EquilibriumSolver::solve_newton(const Eigen::Ref<const Eigen::VectorXd>& s,
                                                   Eigen::Ref<Eigen::VectorXd> x,
                                                   EquilibriumSummary summary) {
  double energy = *summary.energy;
  const double c1 = options_.armijo_parameter;
  // A free object (no attachments): K_total is singular along the rigid motions (§3.6), so six
  // dofs chosen from the start x are held fixed. Π is invariant under rigid motions, so the
  // minimum of the pinned problem is an equilibrium of the free one (the pinned rows of f_net
  // follow from the others by Σ f = 0 and Σ x × f = 0); the caller fixes the rigid frame
  // afterwards (offline/rigid/rigid_stabilisation.hpp, eqs. 19–20).
  if (free_object_) {
    pins_ = rigid_pin_dofs(x);
    if (!pins_) {
      summary.status = EquilibriumStatus::kInvalidInput;
      return summary;
    }
  }
  for (int iteration = 0;; ++iteration) {
    const double residual = gradient_.lpNorm<Eigen::Infinity>();
    summary.iterations = iteration;
    summary.residual_norm = residual;
    summary.energy = energy;
    summary.force_scale = last_force_scale_;
    if (residual <= options_.force_tolerance * last_force_scale_) {
      summary.status = EquilibriumStatus::kConverged;
      return summary;
    }
    if (iteration >= options_.max_iterations) {
      summary.status = EquilibriumStatus::kMaxIterations;
      return summary;
    }
    summary.iterations = iteration + 1;

    // Newton direction: K_total Δx = −f_net, projecting K when the exact one is not PD.
    bool projected = options_.stiffness_projection == StiffnessProjection::kAlways;
    SparseCholeskyStatus factorised = SparseCholeskyStatus::kNotPositiveDefinite;
    for (int attempt = 0; attempt < 2; ++attempt) {
      if (!assemble_total_stiffness(s, x, projected)) {
        summary.status = EquilibriumStatus::kNonFinite;
        return summary;
      }
      factorised = cholesky_.factorise(total_);
      ++summary.factorisations;
      if (projected) ++summary.projected_factorisations;
      if (factorised != SparseCholeskyStatus::kNotPositiveDefinite || projected ||
          options_.stiffness_projection != StiffnessProjection::kOnFailure) {
        break;
      }
      projected = true;
    }
    if (factorised != SparseCholeskyStatus::kOk) {
      summary.status = EquilibriumStatus::kNotPositiveDefinite;
      return summary;
    }
    // A free object: the pinned dofs do not move (their rows of K_total are identity rows), the
    // others take the Newton step of the pinned problem.
    if (pins_) {
      trial_ = gradient_;
      for (Eigen::Index p : *pins_) trial_[p] = 0.0;
    }
    if (cholesky_.solve(pins_ ? trial_ : gradient_, step_) != SparseCholeskyStatus::kOk ||
        !step_.allFinite()) {
      summary.status = EquilibriumStatus::kNonFinite;
      return summary;
    }
    step_ = -step_;
    const double slope = gradient_.dot(step_);  // ∇Πᵀ Δx < 0 for a PD K_total
    if (!(slope < 0.0)) {
      summary.status = EquilibriumStatus::kLineSearchFailed;
      return summary;
    }

    // Backtracking Armijo line search on Π; inverting / non-finite trials are shortened too.
    double alpha = 1.0;
    bool accepted = false;
    for (int k = 0; k < options_.max_line_search_steps; ++k) {
      trial_ = x + alpha * step_;
      const std::optional<double> e = total_energy(s, trial_);
      if (e) {
        const double slack = kEnergyRoundoff * (std::abs(energy) + std::abs(*e));
        if (*e <= energy + c1 * alpha * slope + slack) {
          accepted = true;
          break;
        }
      }
      alpha *= options_.backtracking_factor;
    }
    if (!accepted) {
      summary.status = EquilibriumStatus::kLineSearchFailed;
      return summary;
    }
    x = trial_;
    if (!energy_and_gradient(s, x, &energy)) {
      summary.status = EquilibriumStatus::kNonFinite;
      return summary;
    }
  }
}

EquilibriumSummary EquilibriumSolver::solve_ipopt(const Eigen::Ref<const Eigen::VectorXd>& s,
                                                  Eigen::Ref<Eigen::VectorXd> x,
                                                  EquilibriumSummary summary) {
  if (*summary.residual_norm <= options_.force_tolerance * last_force_scale_) {
    summary.status = EquilibriumStatus::kConverged;  // a warm start at the solution
    return summary;
  }
  const Eigen::VectorXd x0 = x;
  const Eigen::Ref<const Eigen::VectorXd> x0_ref(x0);
  Ipopt::SmartPtr<Ipopt::IpoptApplication> app = new Ipopt::IpoptApplication();
  Ipopt::SmartPtr<detail::EquilibriumIpoptProblem> problem =
      new detail::EquilibriumIpoptProblem(this, &s, &x0_ref);
  {
    Ipopt::SmartPtr<Ipopt::OptionsList> o = app->Options();
    o->SetIntegerValue("print_level", options_.ipopt_print_level);
    o->SetStringValue("sb", "yes");  // no banner
    o->SetIntegerValue("max_iter", options_.max_iterations);
    // Π is scaled by 1/(μh²) so that Ipopt's tol (on the max-norm of the scaled gradient) is the
    // force tolerance against the elastic force scale; the unscaled tolerances are disabled.
    o->SetStringValue("nlp_scaling_method", "none");
    o->SetNumericValue("obj_scaling_factor", 1.0 / elastic_force_scale_);
    o->SetNumericValue("tol", options_.force_tolerance);
    o->SetNumericValue("dual_inf_tol", 1e20);
    o->SetNumericValue("acceptable_tol", 1e3 * options_.force_tolerance);
    o->SetNumericValue("acceptable_dual_inf_tol", 1e20);
    o->SetIntegerValue("acceptable_iter", 5);
    o->SetStringValue("hessian_approximation", "exact");
  }
  const detail::IpoptRun run = detail::run_ipopt(
      *app, Ipopt::GetRawPtr(problem), options_.ipopt_derivative_test,
      options_.ipopt_derivative_test_tolerance, options_.ipopt_derivative_test_perturbation);
  const Ipopt::ApplicationReturnStatus status = run.status;
  summary.ipopt_return_code = static_cast<int>(status);
  summary.derivative_test_errors = run.derivative_test_errors;
  if (run.iterations) summary.iterations = *run.iterations;

  // Keep Ipopt's final point only if it is a valid state no worse than x0.
  double energy = 0.0;
  if (problem->finalized() && problem->x_final().allFinite() &&
      !(options_.reject_inversions && inverts_new_tet(problem->x_final())) &&
      energy_and_gradient(s, problem->x_final(), &energy) && energy <= *summary.energy) {
    x = problem->x_final();
  } else {
    energy_and_gradient(s, x, &energy);
  }
  summary.energy = energy;
  summary.residual_norm = gradient_.lpNorm<Eigen::Infinity>();
  summary.force_scale = last_force_scale_;
  if (*summary.residual_norm <= options_.force_tolerance * last_force_scale_) {
    summary.status = EquilibriumStatus::kConverged;
  } else if (status == Ipopt::Maximum_Iterations_Exceeded) {
    summary.status = EquilibriumStatus::kMaxIterations;
  } else if (status == Ipopt::Invalid_Number_Detected) {
    summary.status = EquilibriumStatus::kNonFinite;
  } else {
    summary.status = EquilibriumStatus::kIpoptFailed;
  }
  return summary;
}

}  // namespace sinew::offline
