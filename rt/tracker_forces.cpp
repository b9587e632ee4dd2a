// Tracker: what the fitted shape says about the loads: the forward verification of the per-node
// forces and the load fit at the named nodes.
#include "rt/tracker.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "rt/centreline.hpp"
#include "rt/detail/order_statistic.hpp"
#include "rt/detail/solver_options.hpp"

namespace sinew::rt {

void Tracker::verify(FrameSummary& summary) {
  // The seed's check: apply f = p(u_T) in a forward static solve and compare with the fit. The
  // solve continues from the previous tracked frame, which is an exact equilibrium of its own
  // forces, stepping the loads to this frame's (forces between consecutive frames, seed 000 §4).
  // A solve from the reference configuration is the fallback (first frame, after a lost frame):
  // with noisy per-node forces a slender beam's path from the reference can end on another branch.
  common::StaticSolverSummary s;
  const bool free = !model_.rigid_motions_constrained();
  bool warm = verify_have_previous_;
  if (warm) {
    u_verify_ = verify_previous_state_;
    verify_loads_prev_ = verify_previous_forces_;
    if (free) {
      // The verification clamps node 0 at its tracked pose: move the previous equilibrium rigidly
      // onto this frame's node 0 (loads rotate with it and stay in equilibrium).
      const double dtheta = u_[2] - u_verify_[2];
      const Eigen::Rotation2Dd R(dtheta);
      const Eigen::Vector2d x0_old = model_.rest_positions().col(0) + u_verify_.segment<2>(0);
      const Eigen::Vector2d x0_new = model_.rest_positions().col(0) + u_.segment<2>(0);
      for (int i = 0; i < model_.num_nodes(); ++i) {
        const Eigen::Vector2d X = model_.rest_positions().col(i);
        const Eigen::Vector2d x = X + u_verify_.segment<2>(3 * i);
        u_verify_.segment<2>(3 * i) = R * (x - x0_old) + x0_new - X;
        u_verify_[3 * i + 2] += dtheta;
        verify_loads_prev_.segment<2>(3 * i) = R * verify_loads_prev_.segment<2>(3 * i);
      }
    }
    // Newton straight to this frame's loads first: it converges to the nearby equilibrium even
    // where that equilibrium is unstable (noisy per-node forces can compress a slender beam past
    // buckling), where a load path would run into a limit point. Then a stepped path.
    verify_backup_ = u_verify_;
    s = verify_solver_direct_.solve(forces_, u_verify_, &verify_loads_prev_);
    if (!s.converged()) {
      u_verify_ = verify_backup_;
      s = verify_solver_warm_.solve(forces_, u_verify_, &verify_loads_prev_);
    }
    warm = s.converged();
  }
  if (!warm) {
    // From the reference configuration (moved rigidly to the tracked pose of node 0 for free
    // beams).
    if (!free) {
      u_verify_.setZero();
    } else {
      const double theta = u_[2];
      const Eigen::Rotation2Dd R(theta);
      const Eigen::Vector2d X0 = model_.rest_positions().col(0);
      for (int i = 0; i < model_.num_nodes(); ++i) {
        const Eigen::Vector2d X = model_.rest_positions().col(i);
        u_verify_.segment<2>(3 * i) = R * (X - X0) + X0 + u_.segment<2>(0) - X;
        u_verify_[3 * i + 2] = theta;
      }
    }
    s = verify_solver_.solve(forces_, u_verify_);
  }
  summary.verified = s.converged();
  if (summary.verified) summary.verify_px = max_node_distance(u_verify_, u_);
  verify_previous_state_ = u_;
  verify_previous_forces_ = forces_;
  verify_have_previous_ = true;
}

void Tracker::fit_loads(FrameSummary& summary) {
  const LoadFitSummary s =
      load_fit_->fit(u_, fit_points_.data(), static_cast<int>(fit_points_.size()));
  const int per_node = options_.fit_moments ? 3 : 2;
  summary.loads_fitted = s.converged;
  fitted_loads_.setZero();
  for (std::size_t k = 0; k < load_nodes_.size(); ++k) {
    fitted_loads_.segment(3 * load_nodes_[k], per_node) =
        load_fit_->loads().segment(per_node * static_cast<Eigen::Index>(k), per_node);
  }
  summary.load_fit_rms_px = s.rms_px;
}

}  // namespace sinew::rt
