// Cost of the beam core: one tangent assembly + block-tridiagonal factor/solve (the inner step of
// both the static solver and the tracker), against a dense LDLT of the same matrix, for 8–128
// elements; and a full static solve of the λ = 3 cantilever.
#include <benchmark/benchmark.h>

#include <Eigen/Dense>

#include "common/beam/static_solver.hpp"

namespace {

using namespace sinew::common;

BeamModel straight_cantilever(int elements) {
  Eigen::Matrix2Xd X(2, elements + 1);
  for (int i = 0; i <= elements; ++i) X.col(i) << double(i) / elements, 0.0;
  BeamDescription d = BeamDescription::uniform(X, {1e6, 1e6, 1.0, 1e-6});
  d.clamp(0);
  return BeamModel(d);
}

Eigen::VectorXd bent_state(const BeamModel& model) {
  Eigen::VectorXd u = Eigen::VectorXd::Zero(model.num_dofs());
  for (int i = 0; i < model.num_nodes(); ++i) {
    const double s = model.rest_positions()(0, i);
    u[3 * i + 1] = 0.2 * s * s;
    u[3 * i + 2] = 0.4 * s;
  }
  return u;
}

void BM_AssembleFactorSolveBanded(benchmark::State& state) {
  const BeamModel model = straight_cantilever(int(state.range(0)));
  const Eigen::VectorXd u = bent_state(model);
  BlockTridiagonal K(model.num_nodes());
  BlockTridiagonalLdlt ldlt(model.num_nodes());
  Eigen::VectorXd p(model.num_dofs());
  for (auto _ : state) {
    Eigen::Ref<Eigen::VectorXd> pr(p);
    model.evaluate(u, nullptr, &pr, &K);
    K.apply_fixed_dofs(model.fixed_mask());
    benchmark::DoNotOptimize(ldlt.factor(K));
    ldlt.solve_in_place(p);
    benchmark::DoNotOptimize(p.data());
  }
  state.SetComplexityN(state.range(0));
}
BENCHMARK(BM_AssembleFactorSolveBanded)->RangeMultiplier(2)->Range(8, 128)->Complexity();

void BM_AssembleFactorSolveDense(benchmark::State& state) {
  const BeamModel model = straight_cantilever(int(state.range(0)));
  const Eigen::VectorXd u = bent_state(model);
  BlockTridiagonal K(model.num_nodes());
  Eigen::VectorXd p(model.num_dofs());
  Eigen::LDLT<Eigen::MatrixXd> ldlt(model.num_dofs());
  Eigen::MatrixXd dense(model.num_dofs(), model.num_dofs());
  for (auto _ : state) {
    Eigen::Ref<Eigen::VectorXd> pr(p);
    model.evaluate(u, nullptr, &pr, &K);
    K.apply_fixed_dofs(model.fixed_mask());
    dense = K.to_dense();
    ldlt.compute(dense);
    p = ldlt.solve(p);
    benchmark::DoNotOptimize(p.data());
  }
  state.SetComplexityN(state.range(0));
}
BENCHMARK(BM_AssembleFactorSolveDense)->RangeMultiplier(2)->Range(8, 128)->Complexity();

void BM_StaticSolveTipLoad(benchmark::State& state) {
  const BeamModel model = straight_cantilever(20);
  Eigen::VectorXd f = Eigen::VectorXd::Zero(model.num_dofs());
  f[model.num_dofs() - 2] = 3.0;  // λ = 3
  StaticSolverOptions options;
  options.load_steps = 12;
  StaticBeamSolver solver(model, options);
  Eigen::VectorXd u(model.num_dofs());
  for (auto _ : state) {
    u.setZero();
    benchmark::DoNotOptimize(solver.solve(f, u).iterations);
  }
}
BENCHMARK(BM_StaticSolveTipLoad)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
