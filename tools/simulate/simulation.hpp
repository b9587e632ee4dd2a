#pragma once
/// sinew-simulate's job (and the Python module's sinew.simulate): the static equilibrium of a
/// geometrically nonlinear plane beam under given loads. The input is the beam JSON of
/// tools/io/beam_json.hpp with "loads", and optionally "steps" (load increments; default from the
/// size of the load, ~4 per unit of P·L²/EI) and "options" (max_iterations_per_step,
/// max_step_cuts, residual_tolerance). Errors throw InputError naming the file and the field.

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <string>

#include "common/beam/beam_model.hpp"
#include "common/beam/static_solver.hpp"

namespace sinew::tools {

struct SimulationCase {
  common::BeamModel model;
  Eigen::VectorXd loads;
  common::StaticSolverOptions options;
};

struct SimulationResult {
  Eigen::VectorXd u;  ///< 3 per node: ux, uy, θ
  common::StaticSolverSummary summary;
};

/// Reads the case from a parsed document; `name` names it in errors.
SimulationCase parse_simulation(const nlohmann::json& doc, const std::string& name);
/// Solves it from the reference configuration.
SimulationResult simulate(const SimulationCase& c);

}  // namespace sinew::tools
