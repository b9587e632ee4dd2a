#include "offline/registration/gauss_newton_options.hpp"

#include <cmath>

#include "common/detail/field_error.hpp"

namespace sinew::offline {
namespace {

std::string invalid(const char* field, double value, const char* constraint) {
  return common::detail::field_error("", field, value, constraint);
}

}  // namespace

std::optional<std::string> GaussNewtonOptions::validate() const {
  if (!(alpha > 0.0 && std::isfinite(alpha))) return invalid("alpha", alpha, "must be > 0");
  if (!(beta >= 0.0 && std::isfinite(beta))) return invalid("beta", beta, "must be >= 0");
  if (max_iterations_per_stage < 0) {
    return invalid("max_iterations_per_stage", max_iterations_per_stage, "must be >= 0");
  }
  if (!(max_marker_error >= 0.0)) {
    return invalid("max_marker_error", max_marker_error, "must be >= 0");
  }
  for (std::size_t i = 0; i < icp_weight_ramp.size(); ++i) {
    const double f = icp_weight_ramp[i];
    if (!(f > 0.0 && f <= 1.0)) {
      const std::string field = "icp_weight_ramp[" + std::to_string(i) + "]";
      return invalid(field.c_str(), f, "must be in (0, 1]");
    }
  }
  if (icp_point_to_plane_iterations < 0) {
    return invalid("icp_point_to_plane_iterations", icp_point_to_plane_iterations, "must be >= 0");
  }
  if (icp_no_progress_iterations < 0) {
    return invalid("icp_no_progress_iterations", icp_no_progress_iterations, "must be >= 0");
  }
  if (!(min_step >= 0.0 && min_step < 1.0))
    return invalid("min_step", min_step, "must be in [0, 1)");
  if (!(max_step > 0.0 && max_step <= 4.0)) {
    return invalid("max_step", max_step, "must be in (0, 4]");
  }
  if (!(relative_decrease_tolerance >= 0.0 && relative_decrease_tolerance < 1.0)) {
    return invalid("relative_decrease_tolerance", relative_decrease_tolerance, "must be in [0, 1)");
  }
  if (!(full_step_acceptance >= 0.0 && full_step_acceptance <= 1.0)) {
    return invalid("full_step_acceptance", full_step_acceptance, "must be in [0, 1]");
  }
  if (line_search_evaluations < 3) {
    return invalid("line_search_evaluations", line_search_evaluations, "must be >= 3");
  }
  if (!(line_search_tolerance > 0.0 && line_search_tolerance < 0.5)) {
    return invalid("line_search_tolerance", line_search_tolerance, "must be in (0, 0.5)");
  }
  if (first_equilibrium_steps < 1) {
    return invalid("first_equilibrium_steps", first_equilibrium_steps, "must be >= 1");
  }
  if (initial_fit_evaluations < 10) {
    return invalid("initial_fit_evaluations", initial_fit_evaluations, "must be >= 10");
  }
  if (!(nullspace_damping >= 0.0 && std::isfinite(nullspace_damping))) {
    return invalid("nullspace_damping", nullspace_damping, "must be >= 0");
  }
  if (!(attachment_stage_damping_floor >= 0.0 && std::isfinite(attachment_stage_damping_floor))) {
    return invalid("attachment_stage_damping_floor", attachment_stage_damping_floor,
                   "must be >= 0");
  }
  if (!(eigenvalue_floor > 0.0 && std::isfinite(eigenvalue_floor))) {
    return invalid("eigenvalue_floor", eigenvalue_floor, "must be > 0");
  }
  if (damped_step_trials < 0 || damped_step_trials > 100)
    return invalid("damped_step_trials", damped_step_trials, "must be in [0, 100]");
  if (!(constant_strain_step_limit >= 0.0 && std::isfinite(constant_strain_step_limit)))
    return invalid("constant_strain_step_limit", constant_strain_step_limit, "must be >= 0");
  if (!(held_penalty_max_bytes >= 0.0 && std::isfinite(held_penalty_max_bytes)))
    return invalid("held_penalty_max_bytes", held_penalty_max_bytes, "must be >= 0");
  if (!(rescue_min_damping >= 0.0 && std::isfinite(rescue_min_damping)))
    return invalid("rescue_min_damping", rescue_min_damping, "must be >= 0");
  if (!(damping_start > 0.0 && std::isfinite(damping_start)))
    return invalid("damping_start", damping_start, "must be > 0");
  if (!(damping_growth > 1.0 && std::isfinite(damping_growth)))
    return invalid("damping_growth", damping_growth, "must be > 1");
  if (auto message = equilibrium.validate()) return "equilibrium." + *message;
  if (auto message = woodbury.validate()) return "woodbury." + *message;
  return std::nullopt;
}

}  // namespace sinew::offline
