#pragma once
/// What a registration reports: one row per Gauss–Newton iteration, how it ended, and the
/// summary a caller prints (brief_report) or logs (full_report).
#include <functional>
#include <string>
#include <vector>

#include "offline/registration/stages.hpp"

namespace sinew::offline {

/// One row of the report: one Gauss–Newton iteration (or the initial fit).
struct GaussNewtonIteration {
  RegistrationStage stage = RegistrationStage::kAttachments;
  int iteration = 0;                ///< within the stage, from 1
  double objective = 0.0;           ///< Φ after the iteration
  double objective_before = 0.0;    ///< Φ at its start (same constraints)
  double predicted_decrease = 0.0;  ///< the Gauss–Newton model's decrease for the full step
  double step = 0.0;                ///< η taken (0: rejected)
  /// Misfit of the stage's markers after the iteration (landmarks or ICP markers; attachments in
  /// the attachment stage), metres.
  double marker_error_mean = 0.0;
  double marker_error_max = 0.0;
  int equilibrium_solves = 0;
  int clamped_tets = 0;           ///< tets whose Fp eigenvalues were clamped
  bool projected_search = false;  ///< the projected-path search ran (projected_search_fallback)
  /// Most tets held by a direction of the iteration (GaussNewtonOptions::hold_clamped_tets), and
  /// whether one was held by elimination (GaussNewtonOptions::held_penalty_max_bytes).
  int held_tets = 0;
  bool held_by_elimination = false;
  /// The step taken ends at an equilibrium with an inverted tet
  /// (GaussNewtonOptions::inverted_equilibrium_fallback).
  bool inverted_equilibrium = false;
  /// μ of the step taken (GaussNewtonOptions::damped_step_trials); 0: the plain Gauss–Newton step.
  double damping = 0.0;
  double jacobian_seconds = 0.0;  ///< tangent factorisation + Z
  double woodbury_seconds = 0.0;  ///< H solve
  double line_search_seconds = 0.0;
  double seconds = 0.0;  ///< whole iteration
};

enum class GaussNewtonTermination {
  kMaxIterations,      ///< the last stage hit its iteration limit
  kMarkerTolerance,    ///< every ICP marker within max_marker_error
  kSmallStep,          ///< η below min_step
  kSmallDecrease,      ///< relative decrease below tolerance
  kLineSearchFailed,   ///< no η in (0, max_step] decreased Φ
  kEquilibriumFailed,  ///< the equilibrium at the start could not be solved
  kLinearSolveFailed,  ///< tangent stiffness not positive definite, or Woodbury failed
  kInvalidInput,       ///< options, sizes, constraints (see message)
  /// A stall, not convergence (issue 51): the last stage ended by a convergence test (small step
  /// or small decrease) with its markers on average farther from their targets than
  /// GaussNewtonOptions::max_marker_error allows at the largest. A failure: message says how far.
  kStalled,
};
const char* to_string(GaussNewtonTermination termination);

struct GaussNewtonSummary {
  GaussNewtonTermination termination = GaussNewtonTermination::kInvalidInput;
  std::string message;  ///< why, for kInvalidInput and the failures
  std::vector<GaussNewtonIteration> iterations;
  double initial_objective = 0.0;  ///< Φ of the final stage's constraints at the template
  double final_objective = 0.0;
  double marker_error_mean = 0.0;  ///< final stage's markers at the end, metres
  double marker_error_max = 0.0;
  int equilibrium_solves = 0;
  double seconds = 0.0;
  bool usable() const {
    return termination != GaussNewtonTermination::kInvalidInput &&
           termination != GaussNewtonTermination::kEquilibriumFailed;
  }
  /// Not usable, or a stall: the state is written but the run did not converge.
  bool failed() const { return !usable() || termination == GaussNewtonTermination::kStalled; }
  std::string brief_report() const;
  std::string full_report() const;
};

/// Called after each iteration (and after the initial fit) for progress output.
using GaussNewtonProgress = std::function<void(const GaussNewtonIteration&)>;

}  // namespace sinew::offline
