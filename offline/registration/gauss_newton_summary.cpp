#include "offline/registration/gauss_newton_summary.hpp"

#include <sstream>

namespace sinew::offline {

const char* to_string(GaussNewtonTermination termination) {
  switch (termination) {
    case GaussNewtonTermination::kMaxIterations:
      return "max-iterations";
    case GaussNewtonTermination::kMarkerTolerance:
      return "marker-tolerance";
    case GaussNewtonTermination::kSmallStep:
      return "small-step";
    case GaussNewtonTermination::kSmallDecrease:
      return "small-decrease";
    case GaussNewtonTermination::kLineSearchFailed:
      return "line-search-failed";
    case GaussNewtonTermination::kEquilibriumFailed:
      return "equilibrium-failed";
    case GaussNewtonTermination::kLinearSolveFailed:
      return "linear-solve-failed";
    case GaussNewtonTermination::kInvalidInput:
      return "invalid-input";
    case GaussNewtonTermination::kStalled:
      return "stalled";
  }
  return "unknown";
}

std::string GaussNewtonSummary::brief_report() const {
  std::ostringstream out;
  out << "Gauss-Newton: " << to_string(termination) << ", " << iterations.size()
      << " iterations, objective " << initial_objective << " -> " << final_objective
      << ", marker error mean " << marker_error_mean << " max " << marker_error_max << ", "
      << equilibrium_solves << " equilibrium solves, " << seconds << " s";
  if (!message.empty()) out << " (" << message << ")";
  return out.str();
}

std::string GaussNewtonSummary::full_report() const {
  std::ostringstream out;
  out << brief_report() << "\n";
  out << "stage        it  objective      step    err_mean     err_max      solves  seconds\n";
  for (const GaussNewtonIteration& it : iterations) {
    out << to_string(it.stage) << "  " << it.iteration << "  " << it.objective << "  " << it.step
        << "  " << it.marker_error_mean << "  " << it.marker_error_max << "  "
        << it.equilibrium_solves << "  " << it.seconds << "\n";
  }
  return out.str();
}

}  // namespace sinew::offline
