#pragma once
/// The static solver settings rt's force checks share: equilibria to 1e-8 of the force scale.

#include <algorithm>

#include "common/beam/static_solver.hpp"

namespace sinew::rt::detail {

/// `steps` load increments of at most `iterations` Newton iterations each, halved at most `cuts`
/// times in all.
inline common::StaticSolverOptions solver_options(int steps, int iterations, int cuts) {
  common::StaticSolverOptions o;
  o.load_steps = std::max(1, steps);
  o.max_iterations_per_step = iterations;
  o.max_step_cuts = cuts;
  o.residual_tolerance = 1e-8;
  return o;
}

}  // namespace sinew::rt::detail
