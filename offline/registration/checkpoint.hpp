#pragma once
/// A registration's checkpoint: the state a run resumes from, bit for bit.
#include <Eigen/Core>
#include <functional>
#include <optional>
#include <vector>

#include "offline/registration/gauss_newton_summary.hpp"

namespace sinew::offline {

/// Everything a registration needs to continue exactly where it stopped. After the initial fit
/// the loop carries no state but (s, x) and its position in the stages: every equilibrium is
/// warm-started from x, ICP closest points and a free object's rigid frame are found at x, and
/// the solvers' factorisations are rebuilt per iteration. So a run resumed from a checkpoint
/// does the same arithmetic as one that never stopped (tools/register writes one to
/// OUTDIR/checkpoint.sinew after every iteration; `sinew-register --resume`).
struct GaussNewtonCheckpoint {
  bool free_object = false;  ///< written by register_free (true) or register_attached (false)
  /// Where to continue: the stage and its iteration (from 1) to run next; std::nullopt when
  /// every stage is done (only the summary is left to compute).
  std::optional<RegistrationStage> next_stage;
  int next_iteration = 1;
  /// The last finished stage's termination: the run's when next_stage is empty.
  GaussNewtonTermination termination = GaussNewtonTermination::kMaxIterations;
  Eigen::VectorXd s;                             ///< 6m plastic state
  Eigen::VectorXd x;                             ///< 3n equilibrium positions
  std::vector<GaussNewtonIteration> iterations;  ///< so far, the initial fit's included
  double initial_objective = 0.0;                ///< GaussNewtonSummary::initial_objective
  int equilibrium_solves = 0;                    ///< so far
  double seconds = 0.0;                          ///< registration time so far
};

/// Called after the initial fit and after each Gauss–Newton iteration (once its stage's
/// termination tests have run) with the state to resume from; for writing checkpoints.
using GaussNewtonCheckpointCallback = std::function<void(const GaussNewtonCheckpoint&)>;

}  // namespace sinew::offline
