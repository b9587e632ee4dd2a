#include "tools/simulate/simulation.hpp"

#include <algorithm>
#include <cmath>

#include "tools/io/beam_json.hpp"

namespace sinew::tools {

SimulationCase parse_simulation(const nlohmann::json& doc, const std::string& name) {
  const JsonCursor root(doc, name);
  root.expect_keys({"nodes", "fixed", "material", "loads", "steps", "options"});
  SimulationCase c{common::BeamModel(parse_beam_description(root)), {}, {}};
  const common::BeamModel& model = c.model;
  if (!model.valid()) throw InputError(name + ": " + model.error());
  c.loads = parse_beam_loads(root, model.num_nodes());
  const Eigen::VectorXd& loads = c.loads;
  common::StaticSolverOptions& options = c.options;
  if (root.has("steps")) {
    const JsonCursor steps = root.at("steps");
    const long s = steps.integer();
    if (s < 1 || s > 100000) steps.fail("= " + std::to_string(s) + " must be in [1, 100000]");
    options.load_steps = static_cast<int>(s);
  } else {
    // Default increments from the size of the load: PL²/EI ≈ load scale; ~4 steps per unit.
    const double L = model.total_length();
    double lambda = 0.0;
    for (int i = 0; i < model.num_dofs(); ++i) {
      lambda = std::max(
          lambda, std::abs(loads[i]) * (i % 3 == 2 ? L : L * L) / model.max_bending_stiffness());
    }
    options.load_steps = std::max(1, static_cast<int>(std::ceil(4.0 * lambda)));
  }
  if (root.has("options")) {
    const JsonCursor o = root.at("options");
    o.expect_keys({"max_iterations_per_step", "max_step_cuts", "residual_tolerance"});
    if (o.has("max_iterations_per_step")) {
      options.max_iterations_per_step = static_cast<int>(o.at("max_iterations_per_step").integer());
    }
    if (o.has("max_step_cuts"))
      options.max_step_cuts = static_cast<int>(o.at("max_step_cuts").integer());
    if (o.has("residual_tolerance")) {
      options.residual_tolerance = o.at("residual_tolerance").finite_number();
    }
  }
  if (auto err = options.validate()) throw InputError(name + ": options." + *err);

  if (!model.rigid_motions_constrained()) {
    throw InputError(
        name + ": fixed: the fixed dofs leave a rigid motion free (" +
        std::to_string(model.num_fixed_dofs()) +
        " fixed), so the static problem is singular; fix e.g. ux, uy and theta of one node");
  }
  return c;
}

SimulationResult simulate(const SimulationCase& c) {
  SimulationResult r;
  r.u = Eigen::VectorXd::Zero(c.model.num_dofs());
  common::StaticBeamSolver solver(c.model, c.options);
  r.summary = solver.solve(c.loads, r.u);
  return r;
}

}  // namespace sinew::tools
