// sinew-simulate: forward static simulation of a plane beam under nodal loads.
//   sinew-simulate --beam beam.json --out state.json
// beam.json: nodes, fixed, material, loads (see tools/io/beam_json.hpp), optional "steps" (load
// increments, default chosen from the load size) and "options" {"max_iterations_per_step",
// "max_step_cuts", "residual_tolerance"}. Writes {"nodes": [[x, y, θ], ...], "converged",
// "iterations", "status", "load_steps", "residual"}.
// Exit status: 0 converged, 1 written but not converged, 2 bad input or usage.
#include <CLI/CLI.hpp>
#include <cmath>
#include <iostream>

#include "common/beam/static_solver.hpp"
#include "tools/io/beam_json.hpp"

namespace {

using namespace sinew;

int run(const std::string& beam_path, const std::string& out_path, bool quiet) {
  const nlohmann::json doc = tools::read_json_file(beam_path);
  const tools::JsonCursor root(doc, beam_path);
  root.expect_keys({"nodes", "fixed", "material", "loads", "steps", "options"});
  common::BeamModel model(tools::parse_beam_description(root));
  if (!model.valid()) throw tools::InputError(beam_path + ": " + model.error());
  const Eigen::VectorXd loads = tools::parse_beam_loads(root, model.num_nodes());

  common::StaticSolverOptions options;
  if (root.has("steps")) {
    const tools::JsonCursor steps = root.at("steps");
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
    const tools::JsonCursor o = root.at("options");
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
  if (auto err = options.validate()) throw tools::InputError(beam_path + ": options." + *err);

  if (!model.rigid_motions_constrained()) {
    throw tools::InputError(
        beam_path + ": fixed: the fixed dofs leave a rigid motion free (" +
        std::to_string(model.num_fixed_dofs()) +
        " fixed), so the static problem is singular; fix e.g. ux, uy and theta of one node");
  }

  Eigen::VectorXd u = Eigen::VectorXd::Zero(model.num_dofs());
  common::StaticBeamSolver solver(model, options);
  const common::StaticSolverSummary summary = solver.solve(loads, u);

  nlohmann::json out;
  out["nodes"] = tools::beam_state_to_json(model, u);
  out["converged"] = summary.converged();
  out["iterations"] = summary.iterations;
  out["status"] = common::to_string(summary.status);
  out["load_steps"] = summary.load_steps_taken;
  out["load_factor"] = summary.load_factor;
  out["residual"] = summary.residual_norm;
  tools::write_json_file(out_path, out);

  if (!quiet) {
    const int tip = model.num_nodes() - 1;
    const Eigen::Matrix2Xd x = model.current_positions(u);
    std::cout.precision(10);
    std::cout << summary.brief_report() << "\n"
              << "tip node " << tip << ": x = " << x(0, tip) << ", y = " << x(1, tip)
              << ", theta = " << u[3 * tip + 2] << "\n"
              << "wrote " << out_path << "\n";
  }
  return summary.converged() ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Static simulation of a geometrically nonlinear plane beam (Sinew)"};
  std::string beam_path, out_path;
  bool quiet = false;
  app.add_option("--beam", beam_path, "beam description (JSON)")->required();
  app.add_option("--out", out_path, "where to write the equilibrium state (JSON)")->required();
  app.add_flag("--quiet", quiet, "print nothing on success");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  try {
    return run(beam_path, out_path, quiet);
  } catch (const sinew::tools::InputError& e) {
    std::cerr << "sinew-simulate: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "sinew-simulate: " << e.what() << "\n";
    return 2;
  }
}
