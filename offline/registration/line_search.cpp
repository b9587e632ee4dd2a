#include "offline/registration/line_search.hpp"

#include <cmath>
#include <limits>

namespace sinew::offline {

BrentResult brent_minimise(const std::function<double(double)>& f, double a, double b,
                           double tolerance, int max_evaluations) {
  // Brent (1973), "Algorithms for minimization without derivatives", ch. 5: keep the best three
  // points (x ≤ w ≤ v by value), try a parabola through them, fall back to golden section.
  const double golden = 0.5 * (3.0 - std::sqrt(5.0));
  const double absolute_tolerance = tolerance * (b - a);
  BrentResult result;
  auto eval = [&](double t) {
    ++result.evaluations;
    const double value = f(t);
    return std::isfinite(value) ? value : std::numeric_limits<double>::max();
  };
  double x = a + golden * (b - a), w = x, v = x;
  double fx = eval(x), fw = fx, fv = fx;
  double d = 0.0, e = 0.0;
  while (result.evaluations < max_evaluations) {
    const double middle = 0.5 * (a + b);
    const double tol1 = absolute_tolerance + 1e-10 * std::abs(x);
    const double tol2 = 2.0 * tol1;
    if (std::abs(x - middle) <= tol2 - 0.5 * (b - a)) break;
    bool golden_step = true;
    if (std::abs(e) > tol1) {
      double r = (x - w) * (fx - fv);
      double q = (x - v) * (fx - fw);
      double p = (x - v) * q - (x - w) * r;
      q = 2.0 * (q - r);
      if (q > 0.0) p = -p;
      q = std::abs(q);
      const double e_previous = e;
      e = d;
      if (std::abs(p) < std::abs(0.5 * q * e_previous) && p > q * (a - x) && p < q * (b - x)) {
        d = p / q;
        const double u = x + d;
        if (u - a < tol2 || b - u < tol2) d = x < middle ? tol1 : -tol1;
        golden_step = false;
      }
    }
    if (golden_step) {
      e = (x < middle) ? b - x : a - x;
      d = golden * e;
    }
    const double u = std::abs(d) >= tol1 ? x + d : x + (d > 0 ? tol1 : -tol1);
    const double fu = eval(u);
    if (fu <= fx) {
      (u < x ? b : a) = x;
      v = w, fv = fw;
      w = x, fw = fx;
      x = u, fx = fu;
    } else {
      (u < x ? a : b) = u;
      if (fu <= fw || w == x) {
        v = w, fv = fw;
        w = u, fw = fu;
      } else if (fu <= fv || v == x || v == w) {
        v = u, fv = fu;
      }
    }
  }
  result.x = x;
  result.value = fx;
  return result;
}

bool take_deferred_inverted_trial(double best_eta, double best_value, double inverted_value) {
  return !(best_eta > 0.0) && inverted_value < best_value;
}

}  // namespace sinew::offline
