#pragma once
/// The line search of the Gauss-Newton registration (seed 003 §3.4): Φ along the step is minimised
/// over η ∈ [0, max_step] by Brent's method (golden section and parabolic interpolation), as in
/// the paper; every evaluation solves an equilibrium, so it counts evaluations, not iterations.

#include <functional>

namespace sinew::offline {

/// Brent's 1D minimisation of f on [a, b] (golden section + parabolic steps), at most
/// max_evaluations calls, stopping when the bracket is below tolerance·(b − a). Returns the best
/// point evaluated and its value. f may return +∞ (treated as a very bad value).
struct BrentResult {
  double x = 0.0;
  double value = 0.0;
  int evaluations = 0;
};
BrentResult brent_minimise(const std::function<double(double)>& f, double a, double b,
                           double tolerance, int max_evaluations);

/// GaussNewtonOptions::inverted_equilibrium_fallback's deferral, on a direction damped below
/// rescue_min_damping: the best trial whose only equilibrium inverts a tet (Φ = inverted_value
/// there, +∞ when none) is taken only when no trial of the iteration lowered Φ (best_eta = 0: the
/// search's best is still the start, Φ = best_value) and it lowers Φ below that.
bool take_deferred_inverted_trial(double best_eta, double best_value, double inverted_value);

}  // namespace sinew::offline
