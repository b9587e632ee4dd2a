#include "common/beam/static_solver.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

namespace sinew::common {

std::optional<std::string> StaticSolverOptions::validate() const {
  if (load_steps < 1) return "load_steps = " + std::to_string(load_steps) + " must be >= 1";
  if (max_iterations_per_step < 1) {
    return "max_iterations_per_step = " + std::to_string(max_iterations_per_step) + " must be >= 1";
  }
  if (max_step_cuts < 0)
    return "max_step_cuts = " + std::to_string(max_step_cuts) + " must be >= 0";
  if (!(displacement_tolerance >= 0.0 && displacement_tolerance <= 1e-3)) {
    std::ostringstream s;
    s << "displacement_tolerance = " << displacement_tolerance << " must be in [0, 1e-3]";
    return s.str();
  }
  if (!(residual_tolerance > 0.0 && residual_tolerance < 1.0)) {
    std::ostringstream s;
    s << "residual_tolerance = " << residual_tolerance << " must be in (0, 1)";
    return s.str();
  }
  return std::nullopt;
}

const char* to_string(StaticSolverStatus status) {
  switch (status) {
    case StaticSolverStatus::kConverged:
      return "converged";
    case StaticSolverStatus::kMaxIterations:
      return "max_iterations";
    case StaticSolverStatus::kSingularSystem:
      return "singular_system";
    case StaticSolverStatus::kNonFinite:
      return "non_finite";
    case StaticSolverStatus::kInvalidInput:
      return "invalid_input";
  }
  return "unknown";
}

std::string StaticSolverSummary::brief_report() const {
  std::ostringstream s;
  s << "static beam solve: " << to_string(status) << ", " << iterations << " Newton iterations, "
    << load_steps_taken << " load steps (" << step_cuts << " cuts), load factor " << load_factor
    << ", residual " << residual_norm;
  if (*message) s << " (" << message << ")";
  return s.str();
}

std::string StaticSolverSummary::full_report() const {
  std::ostringstream s;
  s << "Static beam solver summary\n"
    << "  status             " << to_string(status) << "\n"
    << "  message            " << (*message ? message : "-") << "\n"
    << "  Newton iterations  " << iterations << "\n"
    << "  load steps taken   " << load_steps_taken << "\n"
    << "  step cuts          " << step_cuts << "\n"
    << "  load factor        " << load_factor << "\n"
    << "  scaled residual    " << residual_norm << "\n"
    << "  time (s)           " << seconds << "\n";
  return s.str();
}

StaticBeamSolver::StaticBeamSolver(const BeamModel& model, StaticSolverOptions options)
    : model_(&model), options_(options), options_error_(options.validate()) {
  const int n = model.num_nodes();
  K_.resize(n);
  ldlt_.resize(n);
  const int dofs = model.num_dofs();
  for (Eigen::VectorXd* v : {&f_, &f_start_, &r_, &du_, &u_prev_, &u_last_}) {
    v->setZero(dofs);
  }
}

double StaticBeamSolver::scaled_residual_norm() const {
  // Moments are divided by the beam length so that forces and moments compare.
  const double L = model_->total_length();
  double norm = 0.0;
  for (Eigen::Index i = 0; i < r_.size(); ++i) {
    const double v = (i % 3 == 2) ? r_[i] / L : r_[i];
    norm = std::max(norm, std::abs(v));
  }
  return norm / force_scale_;
}

StaticSolverStatus StaticBeamSolver::newton(Eigen::Ref<Eigen::VectorXd> u,
                                            StaticSolverSummary& summary) {
  const auto& fixed = model_->fixed_mask();
  for (int it = 0; it <= options_.max_iterations_per_step; ++it) {
    Eigen::Ref<Eigen::VectorXd> r(r_);
    model_->evaluate(u, nullptr, &r, &K_);
    r_ -= f_;
    for (Eigen::Index i = 0; i < r_.size(); ++i) {
      if (fixed[i]) r_[i] = 0.0;
    }
    if (!r_.allFinite()) return StaticSolverStatus::kNonFinite;
    summary.residual_norm = scaled_residual_norm();
    if (summary.residual_norm <= options_.residual_tolerance) return StaticSolverStatus::kConverged;
    if (it == options_.max_iterations_per_step) break;

    K_.apply_fixed_dofs(fixed);
    if (!ldlt_.factor(K_)) return StaticSolverStatus::kSingularSystem;
    du_ = -r_;
    ldlt_.solve_in_place(du_);
    if (!du_.allFinite()) return StaticSolverStatus::kNonFinite;
    u += du_;
    ++summary.iterations;
    double step = 0.0;
    const double L = model_->total_length();
    for (Eigen::Index i = 0; i < du_.size(); ++i) {
      step = std::max(step, std::abs(du_[i]) / (i % 3 == 2 ? 1.0 : L));
    }
    if (step <= options_.displacement_tolerance) return StaticSolverStatus::kConverged;
  }
  return StaticSolverStatus::kMaxIterations;
}

StaticSolverSummary StaticBeamSolver::solve(const Eigen::Ref<const Eigen::VectorXd>& loads,
                                            Eigen::Ref<Eigen::VectorXd> u,
                                            const Eigen::VectorXd* start_loads) {
  const auto t0 = std::chrono::steady_clock::now();
  StaticSolverSummary summary;
  auto finish = [&](StaticSolverStatus status, const char* message) {
    summary.status = status;
    summary.message = message;
    summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return summary;
  };

  const int dofs = model_->num_dofs();
  if (!model_->valid()) return finish(StaticSolverStatus::kInvalidInput, "invalid beam model");
  if (options_error_) return finish(StaticSolverStatus::kInvalidInput, "invalid options");
  if (loads.size() != dofs || u.size() != dofs || (start_loads && start_loads->size() != dofs)) {
    return finish(StaticSolverStatus::kInvalidInput, "vector sizes differ from 3 x nodes");
  }
  if (!loads.allFinite() || !u.allFinite() || (start_loads && !start_loads->allFinite())) {
    return finish(StaticSolverStatus::kNonFinite, "loads or start state not finite");
  }
  if (!model_->rigid_motions_constrained()) {
    return finish(StaticSolverStatus::kSingularSystem,
                  "the fixed dofs leave a rigid motion free (translation or rotation): fix more "
                  "dofs");
  }
  if (start_loads) {
    f_start_ = *start_loads;
  } else {
    f_start_.setZero();
  }

  // Force scale for the convergence test: the largest load, or EI/L² for an unloaded beam.
  {
    const double L = model_->total_length();
    double fmax = 0.0;
    for (Eigen::Index i = 0; i < dofs; ++i) {
      const double scale = (i % 3 == 2) ? 1.0 / L : 1.0;
      fmax = std::max({fmax, std::abs(loads[i]) * scale, std::abs(f_start_[i]) * scale});
    }
    force_scale_ = std::max(fmax, model_->max_bending_stiffness() / (L * L));
  }

  const double nominal = 1.0 / options_.load_steps;
  double lambda = 0.0;  // converged load factor
  double increment = nominal;
  double last_increment = 0.0;  // increment that led to the current converged state
  u_last_ = u;
  u_prev_ = u;
  while (lambda < 1.0) {
    const double step = std::min(increment, 1.0 - lambda);
    const double target = (1.0 - lambda - step < 1e-12) ? 1.0 : lambda + step;
    f_ = f_start_ + target * (loads - f_start_);
    if (options_.extrapolate && last_increment > 0.0) {
      u = u_last_ + ((target - lambda) / last_increment) * (u_last_ - u_prev_);
    } else {
      u = u_last_;
    }
    const StaticSolverStatus status = newton(u, summary);
    if (status == StaticSolverStatus::kConverged) {
      u_prev_ = u_last_;
      u_last_ = u;
      last_increment = target - lambda;
      lambda = target;
      summary.load_factor = lambda;
      ++summary.load_steps_taken;
      increment = std::min(nominal, 2.0 * increment);
      continue;
    }
    // Failed increment: back to the last converged state, halve the increment and retry.
    u = u_last_;
    if (summary.step_cuts >= options_.max_step_cuts) {
      switch (status) {
        case StaticSolverStatus::kSingularSystem:
          return finish(status, "tangent stiffness singular at a load step");
        case StaticSolverStatus::kNonFinite:
          return finish(status, "state or residual became non-finite");
        default:
          return finish(StaticSolverStatus::kMaxIterations,
                        "a load step did not converge after the allowed step cuts");
      }
    }
    ++summary.step_cuts;
    increment = 0.5 * step;
  }
  return finish(StaticSolverStatus::kConverged, "");
}

}  // namespace sinew::common
