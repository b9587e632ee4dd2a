#pragma once
/// Static equilibrium of a plane beam under nodal loads: p(u) = f on the free dofs (seed 000, eq.
/// 8, with f the applied load), by Newton–Raphson on K_T du = −(p(u) − f) with load stepping.
///
/// Load steps go from the start loads (zero unless given) to the target loads in equal increments;
/// each step is warm-started by extrapolating the last two converged states, and a step that does
/// not converge is halved and retried. The solver is sized once at construction: solve() does not
/// allocate, so the real-time tracker can run a verification solve inside a frame.

#include <Eigen/Core>
#include <optional>
#include <string>

#include "common/beam/beam_model.hpp"
#include "common/beam/block_tridiagonal.hpp"

namespace sinew::common {

struct StaticSolverOptions {
  /// Number of equal load increments from the start loads to the target loads, ≥ 1. Large
  /// deflections need more (the elastica at λ = PL²/EI = 10 converges with 10–40).
  int load_steps = 1;
  /// Newton iterations allowed per load increment, ≥ 1.
  int max_iterations_per_step = 30;
  /// How many times a failed increment may be halved in total before giving up, ≥ 0.
  int max_step_cuts = 10;
  /// Convergence: ‖r‖∞ ≤ residual_tolerance · force scale, with moments divided by the beam length
  /// and the force scale max(‖f‖∞, EI/L²). In (0, 1).
  double residual_tolerance = 1e-9;
  /// Also converged when a Newton correction moves no dof by more than this, relative to the beam
  /// length (rotations: absolute). Catches round-off floors of very slender beams (EA·L²/EI ≳ 1e6),
  /// whose residual cannot fall below ~1e-9 of the load. In [0, 1e-3].
  double displacement_tolerance = 1e-12;
  /// Predict each increment's start as u_k + (Δλ_new/Δλ_old)(u_k − u_{k−1}) instead of u_k.
  bool extrapolate = true;

  /// Empty when valid; otherwise one line naming the field, its value and the constraint.
  std::optional<std::string> validate() const;
};

enum class StaticSolverStatus {
  kConverged,       ///< the target loads are in equilibrium with u
  kMaxIterations,   ///< an increment failed even after max_step_cuts halvings
  kSingularSystem,  ///< K_T could not be factorised (e.g. a free beam: rigid motions not fixed)
  kNonFinite,       ///< NaN or infinity in the state or residual
  kInvalidInput,    ///< invalid options, model, or vector sizes
};

const char* to_string(StaticSolverStatus status);

struct StaticSolverSummary {
  StaticSolverStatus status = StaticSolverStatus::kInvalidInput;
  int iterations = 0;          ///< Newton iterations over all increments
  int load_steps_taken = 0;    ///< converged increments
  int step_cuts = 0;           ///< increments halved after a failure
  double load_factor = 0.0;    ///< fraction of the way to the target loads that was reached, [0, 1]
  double residual_norm = 0.0;  ///< final scaled ‖r‖∞ (see residual_tolerance)
  double seconds = 0.0;
  const char* message = "";  ///< static text with the reason for a failure

  bool converged() const { return status == StaticSolverStatus::kConverged; }
  std::string brief_report() const;
  std::string full_report() const;
};

class StaticBeamSolver {
 public:
  /// The model must outlive the solver.
  explicit StaticBeamSolver(const BeamModel& model, StaticSolverOptions options = {});

  const StaticSolverOptions& options() const { return options_; }

  /// Solves p(u) = loads on the free dofs. On entry u holds the start state, assumed in equilibrium
  /// with start_loads (zero when null); its fixed dofs keep their values (prescribed
  /// displacements, usually 0). On exit u holds the last converged state. loads: 3n (forces and
  /// moments per node; entries on fixed dofs are reactions and are ignored). No allocation.
  StaticSolverSummary solve(const Eigen::Ref<const Eigen::VectorXd>& loads,
                            Eigen::Ref<Eigen::VectorXd> u,
                            const Eigen::VectorXd* start_loads = nullptr);

 private:
  // Newton iterations at fixed load f_ ; returns the status of this increment.
  StaticSolverStatus newton(Eigen::Ref<Eigen::VectorXd> u, StaticSolverSummary& summary);
  double scaled_residual_norm() const;

  const BeamModel* model_;
  StaticSolverOptions options_;
  std::optional<std::string> options_error_;
  double force_scale_ = 1.0;
  BlockTridiagonal K_;
  BlockTridiagonalLdlt ldlt_;
  Eigen::VectorXd f_, f_start_, r_, du_, u_prev_, u_last_;
};

}  // namespace sinew::common
