// The Gauss–Newton linear algebra of seed 003 (§3.4, Table 1) on a box of tets: one solve with
// H = L² + ZᵀZ by the Woodbury identity (eq. 14) against conjugate gradients on the same system
// (the paper's CG baseline), and one whole Gauss–Newton iteration (tangent factorisation, Z, the
// Woodbury step, the Brent line search over equilibrium solves).
//
// Sizes: "small" 8x8x4 cubes (1,536 tets, 60 markers) and "large" 25x25x8 cubes (30,000 tets,
// 300 markers: 6m = 180,000 unknowns, 900 constraint rows). The bottom face is attached (springs
// in f_net); the markers are landmarks on the top face pulled 1 cm outwards and up, so that Z is
// what a registration sees. Counters: seconds per phase, CG iterations, the relative difference
// CG vs Woodbury, and the speed ratio. CG runs until it agrees with Woodbury to 1e-6 (relative
// residual 1e-12) or hits its time cap (cg_capped = 1: the ratio is then a lower bound).

#include <benchmark/benchmark.h>

#include <Eigen/Core>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <memory>
#include <random>

#include "common/material/stable_neo_hookean.hpp"
#include "common/timing.hpp"
#include "offline/constraints/constraints.hpp"
#include "offline/linalg/woodbury_solver.hpp"
#include "offline/plastic/plastic_elastic_energy.hpp"
#include "offline/plastic/plastic_strain_laplacian.hpp"
#include "offline/registration/gauss_newton.hpp"
#include "tests/support/tet_mesh_fixtures.hpp"

namespace {

using namespace sinew;
using namespace sinew::offline;
using Clock = std::chrono::steady_clock;

using common::seconds_since;

struct Problem {
  Eigen::MatrixXd rest;
  common::TetIndices tets;
  std::optional<PlasticElasticEnergy> energy;
  RegistrationConstraints constraints;
  std::optional<PointConstraints> springs;
  std::optional<PointConstraints> markers;  // the objective rows (landmarks, weight α)
  PlasticStrainLaplacian laplacian;
  Eigen::MatrixXd Zt;  // Zᵀ, 6m x r
  Eigen::VectorXd gradient;
  double jacobian_seconds = 0.0;
};

EmbeddedPoint at_vertex(const common::TetIndices& tets, int v) {
  for (Eigen::Index t = 0; t < tets.rows(); ++t)
    for (int a = 0; a < 4; ++a)
      if (tets(t, a) == v) {
        EmbeddedPoint e;
        e.tet = t;
        e.weights = Eigen::Vector4d::Unit(a);
        return e;
      }
  return {};
}

Problem& problem(bool large) {
  static std::map<bool, std::unique_ptr<Problem>> cache;
  auto& slot = cache[large];
  if (slot) return *slot;
  slot = std::make_unique<Problem>();
  Problem& p = *slot;
  const int n = large ? 25 : 8, nz = large ? 8 : 4, markers = large ? 300 : 60;
  testing::TetMesh box = testing::make_box_mesh(n, n, nz, 0.004);
  p.rest = std::move(box.rest_positions);
  p.tets = std::move(box.tets);
  common::StableNeoHookeanParameters material;
  material.youngs_modulus = 1e4;
  material.poisson_ratio = 0.4;
  p.energy =
      PlasticElasticEnergy::create(p.rest, p.tets, *common::StableNeoHookean::create(material));
  std::vector<int> top;
  const double z_top = p.rest.col(2).maxCoeff();
  for (int v = 0; v < p.rest.rows(); ++v) {
    if (p.rest(v, 2) < 1e-12) {
      PointConstraint c;
      c.kind = ConstraintKind::kAttachment;
      c.point = at_vertex(p.tets, v);
      c.target = p.rest.row(v).transpose();
      c.weight = 1e3;
      p.constraints.attachments.push_back(c);
    } else if (p.rest(v, 2) > z_top - 1e-12) {
      top.push_back(v);
    }
  }
  std::mt19937 rng(3);
  std::shuffle(top.begin(), top.end(), rng);
  const Eigen::Vector3d centre = p.rest.colwise().mean().transpose();
  std::vector<PointConstraint> rows;
  for (int i = 0; i < markers; ++i) {
    PointConstraint c;
    c.kind = ConstraintKind::kLandmark;
    c.point = at_vertex(p.tets, top[static_cast<std::size_t>(i)]);
    const Eigen::Vector3d X = p.rest.row(top[static_cast<std::size_t>(i)]).transpose();
    Eigen::Vector3d radial = X - centre;
    radial.z() = 0.0;
    c.target = X + 0.01 * radial.normalized() + Eigen::Vector3d(0, 0, 0.01);
    p.constraints.landmarks.push_back(c);
    c.weight = GaussNewtonOptions{}.alpha;
    rows.push_back(c);
  }
  p.springs = PointConstraints::create(p.rest.rows(), p.tets, p.constraints.attachments);
  p.markers = PointConstraints::create(p.rest.rows(), p.tets, rows);
  p.laplacian = make_plastic_strain_laplacian(p.tets);
  // Z and the gradient at the template (s = I, x = rest: the equilibrium under rest attachments).
  const Eigen::VectorXd s = identity_plastic_strains(p.tets.rows());
  const Eigen::VectorXd x = p.energy->rest_dofs();
  SparseCholesky tangent;
  const Clock::time_point start = Clock::now();
  auto jacobian = constraint_jacobian(*p.energy, *p.springs, *p.markers, s, x, tangent);
  p.jacobian_seconds = seconds_since(start);
  p.Zt = std::move(jacobian->Zt);
  p.gradient = p.Zt * jacobian->residual;  // L²s = 0 at s = I
  return p;
}

// The Woodbury solve of H y = −g as the reference answer, kept for the CG comparison.
std::map<bool, Eigen::VectorXd>& woodbury_answers() {
  static std::map<bool, Eigen::VectorXd> answers;
  return answers;
}
std::map<bool, double>& woodbury_seconds() {
  static std::map<bool, double> seconds;
  return seconds;
}

void BM_WoodburySolve(benchmark::State& state) {
  const bool large = state.range(0) == 1;
  Problem& p = problem(large);
  for (auto _ : state) {
    Eigen::MatrixXd Zt = p.Zt;  // the copy is not timed: a registration moves its Zᵀ in
    const Clock::time_point start = Clock::now();
    auto solver = WoodburySolver::create(p.laplacian.adjacency, p.tets.rows());
    const double factor_seconds = seconds_since(start);
    solver->set_constraint_rows_transposed(std::move(Zt));
    Eigen::VectorXd y(p.gradient.size());
    solver->solve(-p.gradient, y);
    const double total = seconds_since(start);
    state.SetIterationTime(total);
    woodbury_answers()[large] = y;
    woodbury_seconds()[large] = total;
    state.counters["tets"] = static_cast<double>(p.tets.rows());
    state.counters["rows"] = static_cast<double>(p.Zt.cols());
    state.counters["prep_tangent_and_Z_s"] = p.jacobian_seconds;
    state.counters["factor_s"] = factor_seconds;
    state.counters["base_solves_s"] = solver->base_solve_seconds();
    state.counters["capacitance_s"] = solver->capacitance_seconds();
    // Its true relative residual ‖h − Hy‖/‖h‖: how far any two answers can differ is this times
    // the conditioning of H (the CG comparison cannot be tighter than that).
    Eigen::VectorXd Hy(y.size());
    apply_gauss_newton_hessian(p.laplacian.matrix, p.Zt, y, Hy);
    state.counters["woodbury_relative_residual"] = (Hy + p.gradient).norm() / p.gradient.norm();
  }
}
BENCHMARK(BM_WoodburySolve)
    ->Arg(0)
    ->Arg(1)
    ->Iterations(1)
    ->UseManualTime()
    ->Unit(benchmark::kSecond);

void BM_ConjugateGradientSolve(benchmark::State& state) {
  const bool large = state.range(0) == 1;
  Problem& p = problem(large);
  const Eigen::VectorXd& reference = woodbury_answers()[large];
  for (auto _ : state) {
    ConjugateGradientOptions options;
    options.relative_tolerance = 1e-12;
    options.max_iterations = 10000000;
    // SINEW_CG_MAX_SECONDS lifts the cap (the large case needs about an hour to agree to 1e-6).
    const char* cap = std::getenv("SINEW_CG_MAX_SECONDS");
    options.max_seconds = cap ? std::atof(cap) : large ? 1200.0 : 600.0;
    // CG stops once it agrees with the Woodbury answer to 1e-6 (the acceptance criterion), and
    // prints its progress (the large case runs for an hour).
    const Clock::time_point cg_start = Clock::now();
    double agreement = std::numeric_limits<double>::infinity();
    if (reference.size() == p.gradient.size()) {
      options.progress = [&](int iteration, const Eigen::VectorXd& y, double residual) {
        agreement = (y - reference).norm() / reference.norm();
        std::fprintf(stderr, "CG %d: %.0f s, relative residual %.2e, vs Woodbury %.2e\n", iteration,
                     seconds_since(cg_start), residual, agreement);
        return agreement > 1e-6;
      };
      options.progress_every = large ? 250 : 100;
    }
    Eigen::VectorXd y(p.gradient.size());
    const ConjugateGradientSummary summary =
        conjugate_gradient_solve(p.laplacian.matrix, p.Zt, -p.gradient, y, options);
    state.SetIterationTime(summary.seconds);
    state.counters["cg_iterations"] = summary.iterations;
    state.counters["cg_relative_residual"] = summary.relative_residual;
    state.counters["cg_capped"] = summary.seconds >= options.max_seconds ? 1.0 : 0.0;
    if (reference.size() == y.size()) {
      state.counters["cg_vs_woodbury"] = (y - reference).norm() / reference.norm();
      state.counters["cg_over_woodbury"] = summary.seconds / woodbury_seconds()[large];
    }
  }
}
BENCHMARK(BM_ConjugateGradientSolve)
    ->Arg(0)
    ->Arg(1)
    ->Iterations(1)
    ->UseManualTime()
    ->Unit(benchmark::kSecond);

void BM_GaussNewtonIteration(benchmark::State& state) {
  const bool large = state.range(0) == 1;
  Problem& p = problem(large);
  for (auto _ : state) {
    GaussNewtonOptions options;
    options.initial_constant_fit = false;
    // Two iterations; the second is timed: it is what every later iteration of a long run costs
    // (work matrices are reused from the first, as they are from then on).
    options.max_iterations_per_stage = 2;
    options.max_marker_error = 0.0;
    options.relative_decrease_tolerance = 0.0;
    options.beta = 0.0;
    const RegistrationResult result = register_attached(*p.energy, p.constraints, nullptr, options);
    double seconds = 0.0;
    for (const GaussNewtonIteration& it : result.summary.iterations) {
      if (it.stage != RegistrationStage::kLandmarks) continue;
      if (seconds == 0.0) state.counters["first_iteration_s"] = it.seconds;
      seconds = it.seconds;
      state.counters["jacobian_s"] = it.jacobian_seconds;
      state.counters["woodbury_s"] = it.woodbury_seconds;
      state.counters["line_search_s"] = it.line_search_seconds;
      state.counters["equilibrium_solves"] = it.equilibrium_solves;
      state.counters["step"] = it.step;
      state.counters["marker_error_max_mm"] = 1e3 * it.marker_error_max;
    }
    state.SetIterationTime(seconds);
  }
}
BENCHMARK(BM_GaussNewtonIteration)
    ->Arg(0)
    ->Arg(1)
    ->Iterations(1)
    ->UseManualTime()
    ->Unit(benchmark::kSecond);

}  // namespace

BENCHMARK_MAIN();
