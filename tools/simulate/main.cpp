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
#include "tools/simulate/simulation.hpp"

namespace {

using namespace sinew;

int run(const std::string& beam_path, const std::string& out_path, bool quiet) {
  const tools::SimulationCase c = tools::parse_json_file(beam_path, [&](const nlohmann::json& doc) {
    return tools::parse_simulation(doc, beam_path);
  });
  const common::BeamModel& model = c.model;
  const tools::SimulationResult result = tools::simulate(c);
  const Eigen::VectorXd& u = result.u;
  const common::StaticSolverSummary& summary = result.summary;

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
