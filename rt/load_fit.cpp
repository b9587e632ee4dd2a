#include "rt/load_fit.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/detail/field_error.hpp"
#include "rt/detail/order_statistic.hpp"
#include "rt/detail/solver_options.hpp"

namespace sinew::rt {

namespace {

// Every element split into `parts` straight sub-elements, so that its discretisation error (O(h²))
// does not masquerade as a load. Tracked node k is fine node k·parts.
common::BeamDescription subdivided_description(const common::BeamDescription& beam, int parts) {
  const common::BeamModel probe(beam);
  if (!probe.valid() || parts <= 1) return beam;
  const Eigen::Index n = beam.rest_positions.cols();
  common::BeamDescription d;
  d.rest_positions.resize(2, (n - 1) * parts + 1);
  for (Eigen::Index e = 0; e + 1 < n; ++e) {
    for (int k = 0; k < parts; ++k) {
      d.rest_positions.col(e * parts + k) =
          beam.rest_positions.col(e) +
          (double(k) / parts) * (beam.rest_positions.col(e + 1) - beam.rest_positions.col(e));
      d.sections.push_back(beam.sections[e]);
      if (!beam.prestress.empty()) d.prestress.push_back(beam.prestress[e]);
    }
  }
  d.rest_positions.col((n - 1) * parts) = beam.rest_positions.col(n - 1);
  if (!beam.fixed.empty()) {
    d.fixed.assign(3 * d.rest_positions.cols(), 0);
    for (Eigen::Index i = 0; i < n; ++i) {
      for (int a = 0; a < 3; ++a) d.fixed[3 * i * parts + a] = beam.fixed[3 * i + a];
    }
  }
  return d;
}

// A step moving no node by more than this ends the fit, pixels.
constexpr double kConvergedPx = 1e-3;
// Each step may move a node by at most this, pixels.
constexpr double kMaxStepPx = 20.0;

}  // namespace

std::optional<std::string> LoadFitOptions::validate() const {
  auto error = [](const char* name, double value, const char* constraint) {
    return common::detail::field_error("load fit options.", name, value, constraint);
  };
  if (max_iterations < 1) return error("max_iterations", max_iterations, "must be >= 1");
  if (subdivisions < 1) return error("subdivisions", subdivisions, "must be >= 1");
  if (max_load_points < 1 || max_load_points > 64) {
    return error("max_load_points", max_load_points, "must be in [1, 64]");
  }
  return std::nullopt;
}

LoadFit::LoadFit(const common::BeamDescription& beam, LoadFitOptions options)
    : options_(options),
      model_(subdivided_description(beam, std::max(1, options.subdivisions))),
      solver_(model_, detail::solver_options(1, 25, 10)) {
  if (auto err = options_.validate()) {
    error_ = *err;
    return;
  }
  if (!model_.valid()) {
    error_ = model_.error();
    return;
  }
  if (!model_.rigid_motions_constrained()) {
    error_ =
        "load fit: the beam needs fixed dofs that hold it (e.g. a clamped node): a free beam "
        "cannot carry loads at a few points in equilibrium";
    return;
  }
  if (options_.fit_base_rotation && !model_.fixed_mask()[2]) {
    error_ = "load fit: fit_base_rotation needs node 0's rotation fixed (a clamped first node)";
    return;
  }
  if (options_.fit_base_translation && !(model_.fixed_mask()[0] && model_.fixed_mask()[1])) {
    error_ = "load fit: fit_base_translation needs node 0's position fixed (a clamped first node)";
    return;
  }
  const common::BeamModel coarse(beam);
  parts_ = options_.subdivisions;
  n_ = coarse.num_nodes();
  per_point_ = options_.fit_moments ? 3 : 2;
  base_ = 0;
  if (options_.fit_base_rotation) base_dofs_[base_++] = 2;
  if (options_.fit_base_translation) {
    base_dofs_[base_++] = 0;
    base_dofs_[base_++] = 1;
  }
  const int max_params = per_point_ * options_.max_load_points + base_;
  const int dofs = model_.num_dofs();
  for (Eigen::VectorXd* v : {&u_, &loads_prev_, &rhs_, &du_, &z_, &u_backup_}) v->setZero(dofs);
  columns_.setZero(dofs, max_params + 1);  // + the coupled fit's Newton step
  residual_.setZero(3 * n_);
  change_.setZero(3 * n_);
  q_.setZero(max_params);
  q_backup_.setZero(max_params);
  dq_.setZero(max_params);
  g_.setZero(max_params);
  jacobian_.setZero(3 * n_, max_params);
  weighted_jacobian_.setZero(3 * n_, max_params);
  normal_.setZero(max_params, max_params);
  covariance_.setZero(max_params, max_params);
  sandwich_.setZero(max_params, max_params);
  support_columns_.setZero(dofs, 3);
  support_jacobian_.setZero(3 * n_, 3);
  support_sensitivity_.setZero(max_params, 3);
  ldlt_ = Eigen::LDLT<Eigen::MatrixXd>(max_params);
  sorted_.setZero(n_);
  weights_.setOnes(n_);
  rotation_scale_ = coarse.total_length() / coarse.num_elements();
  tangent_.resize(model_.num_nodes());
  factor_.resize(model_.num_nodes());
}

void LoadFit::reset() noexcept {
  for (double& b : base_offsets_) b = 0.0;
  u_.setZero();
  loads_prev_.setZero();
  q_.setZero();
}

void LoadFit::add_loads(Eigen::VectorXd& f, double sign) const {
  for (int k = 0; k * pp_ < params_; ++k) {
    if (fractional_) {
      const auto& c = consistent_[k];
      const int a = 3 * points_[k];
      for (int i = 0; i < 3; ++i) {
        f[a + i] += sign * q_[k] * c[i];
        if (c[3 + i] != 0.0) f[a + 3 + i] += sign * q_[k] * c[3 + i];
      }
    } else if (directions_) {
      const Eigen::Vector2d d(directions_[2 * k], directions_[2 * k + 1]);
      f.segment<2>(3 * points_[k]) += sign * q_[k] * d;
    } else {
      f.segment(3 * points_[k], pp_) += sign * q_.segment(pp_ * k, pp_);
    }
  }
}

void LoadFit::unit_load(int j, Eigen::Ref<Eigen::VectorXd> z) const {
  const auto& fixed = model_.fixed_mask();
  z.setZero();
  const int k = j / pp_;
  if (fractional_) {
    const auto& c = consistent_[k];
    const int a = 3 * points_[k];
    for (int i = 0; i < 6; ++i) {
      if (c[i] != 0.0 && !fixed[a + i]) z[a + i] = c[i];
    }
  } else if (directions_) {
    for (int c = 0; c < 2; ++c) {
      const int dof = 3 * points_[k] + c;
      if (!fixed[dof]) z[dof] = directions_[2 * k + c];
    }
  } else {
    const int dof = 3 * points_[k] + j % pp_;
    if (!fixed[dof]) z[dof] = 1.0;
  }
}

void LoadFit::take_supports(const Eigen::Ref<const Eigen::VectorXd>& tracked,
                            Eigen::VectorXd& u) const {
  const auto& fixed = model_.fixed_mask();
  for (int i = 0; i < n_; ++i) {
    for (int c = 0; c < 3; ++c) {
      const int d = 3 * parts_ * i + c;
      if (fixed[d]) u[d] = tracked[3 * i + c];
    }
  }
  for (int k = 0; k < base_; ++k) u[base_dofs_[k]] = tracked[base_dofs_[k]] + q_[params_ + k];
}

bool LoadFit::parameter_columns(bool newton_step) {
  // Node 0's dofs couple to fine node 1 only (the tangent is block-tridiagonal); a support dof d
  // moved by 1 moves the free dofs by −K_ff⁻¹ K_f,d.
  base_coupling_ = tangent_.lower(0);
  const Eigen::Matrix3d& base_coupling = base_coupling_;
  tangent_.apply_fixed_dofs(model_.fixed_mask());
  if (!factor_.factor(tangent_)) return false;
  // Every right-hand side first, then one solve for all of them (columns side by side: 0.6x the
  // time of one solve per column).
  const int p = params_ + base_;
  for (int j = 0; j < p; ++j) {
    auto z = columns_.col(j);
    if (j < params_) {
      unit_load(j, z);
    } else {
      z.setZero();
      z.segment<3>(3) = -base_coupling.col(base_dofs_[j - params_]);
    }
  }
  if (newton_step) columns_.col(p) = -rhs_;
  factor_.solve_columns_in_place(columns_.leftCols(newton_step ? p + 1 : p));
  if (newton_step) du_ = columns_.col(p);
  for (int j = 0; j < p; ++j) {
    auto z = columns_.col(j);
    if (j >= params_) z[base_dofs_[j - params_]] = 1.0;
    for (int i = 0; i < n_; ++i) {
      jacobian_.block<2, 1>(3 * i, j) = z.segment<2>(3 * parts_ * i);
      jacobian_(3 * i + 2, j) = rotation_scale_ * z[3 * parts_ * i + 2];
    }
    // The tracked follicle dofs the fitted ones replace are not measurements here.
    for (int k = 0; k < base_; ++k) jacobian_(base_dofs_[k], j) = 0.0;
  }
  return true;
}

void LoadFit::residual(const Eigen::Ref<const Eigen::VectorXd>& tracked, const Eigen::VectorXd& u) {
  for (int i = 0; i < n_; ++i) {
    residual_.segment<2>(3 * i) = u.segment<2>(3 * parts_ * i) - tracked.segment<2>(3 * i);
    residual_[3 * i + 2] = rotation_scale_ * (u[3 * parts_ * i + 2] - tracked[3 * i + 2]);
  }
  for (int k = 0; k < base_; ++k) residual_[base_dofs_[k]] = 0.0;
}

// The robust Gauss–Newton step on the loads from jacobian_ (tracked nodes per load parameter) and
// residual_ (the tracked nodes' misfit at dq = 0) into dq_. Tukey weights per node, scale
// 1.4826·median with a floor of 0.05 px. The constant is tighter than the image term's: a load
// must explain the whole shape, and a kink of 0.2–0.3 px at a clutter crossing otherwise moves a
// thin beam's tip load by ~2 % (measured: 5.5 % → 4.5 %). Components the shape barely determines
// (an axial force on a nearly straight beam) are held by a small ridge. False when the step is not
// finite.
bool LoadFit::step(bool robust, bool scaled_ridge) {
  const int p = params_ + base_;
  auto J = jacobian_.leftCols(p);
  auto WJ = weighted_jacobian_.leftCols(p);
  if (robust) {
    constexpr double kLoadFitTukey = 2.5;
    for (int i = 0; i < n_; ++i)
      sorted_[i] = static_cast<float>(residual_.segment<3>(3 * i).norm());
    const double cut =
        kLoadFitTukey *
        std::max(1.4826 * double(detail::kth_smallest(sorted_.data(), n_, n_ / 2)), 0.05);
    for (int i = 0; i < n_; ++i) {
      const double r = residual_.segment<3>(3 * i).norm() / cut;
      const double w = r < 1.0 ? (1.0 - r * r) * (1.0 - r * r) : 0.0;
      weights_[i] = w;
      WJ.middleRows<3>(3 * i) = w * J.middleRows<3>(3 * i);
    }
  } else {
    weights_.setOnes();
    WJ = J;
  }
  auto N = normal_.topLeftCorner(p, p);
  N.noalias() = WJ.transpose() * J;
  g_.head(p).noalias() = WJ.transpose() * residual_;
  // The coupled fit: a ridge of 1e-6 of each parameter's own diagonal (Marquardt's scaling).
  // One of the largest diagonal, as before, damped the follicle angle's step by ~45 % (its
  // diagonal is 1e-6 of a contact force's in these units), so the fit crept along the valley
  // where a load and a turn of the follicle look alike and stopped short of the minimum: on the
  // shared renderer's elastica with 0.1 px of node noise the follicle moment read 10-14 % off
  // (median) where it reads 1.0-1.6 % now, 6 SDs from the truth where 0.3-0.8
  // (tests/rt/test_load_fit_elastica.cpp). The nested fallback keeps the largest diagonal's:
  // its steps are not linearised about an equilibrium, and without that damping a free force's
  // poorly seen axial part runs away (LoadFitMethods.FollowsALoadPointThatMovesAlongTheBeam).
  const double largest = 1e-6 * N.diagonal().maxCoeff() + 1e-300;
  for (int j = 0; j < p; ++j) N(j, j) += scaled_ridge ? 1e-6 * N(j, j) + 1e-300 : largest;
  // The same count as the last call: the factorisation's storage is reused (no allocation).
  ldlt_.compute(N);
  if (ldlt_.info() != Eigen::Success) return false;
  auto dq = dq_.head(p);
  dq = -g_.head(p);
  ldlt_.solveInPlace(dq);
  return dq_.head(p).allFinite();
}

bool LoadFit::coupled(const Eigen::Ref<const Eigen::VectorXd>& tracked, int* iterations,
                      bool* equilibrium) {
  const int p = params_ + base_;
  *equilibrium = false;
  const auto& fixed = model_.fixed_mask();
  const int dofs = model_.num_dofs();
  // Start from the tracked shape: the last call's state moved by this call's change at the
  // tracked nodes, interpolated linearly between them (the answer lies within the fit's misfit of
  // this shape).
  for (int i = 0; i < n_; ++i) {
    residual_.segment<3>(3 * i) = tracked.segment<3>(3 * i) - u_.segment<3>(3 * parts_ * i);
  }
  for (int i = 0; i + 1 < n_; ++i) {
    for (int k = 0; k < parts_; ++k) {
      const double a = static_cast<double>(k) / parts_;
      for (int c = 0; c < 3; ++c) {
        const int d = 3 * (parts_ * i + k) + c;
        if (!fixed[d]) u_[d] += (1.0 - a) * residual_[3 * i + c] + a * residual_[3 * (i + 1) + c];
      }
    }
  }
  for (int c = 0; c < 3; ++c) {
    const int d = 3 * parts_ * (n_ - 1) + c;
    if (!fixed[d]) u_[d] += residual_[3 * (n_ - 1) + c];
  }
  take_supports(tracked, u_);
  for (int it = 0; it < 2 * options_.max_iterations; ++it) {
    ++*iterations;
    Eigen::Ref<Eigen::VectorXd> r(rhs_);
    model_.evaluate(u_, nullptr, &r, &tangent_);
    add_loads(rhs_, -1.0);
    for (int d = 0; d < dofs; ++d) {
      if (fixed[d]) rhs_[d] = 0.0;
    }
    // Jacobian columns and the Newton step −K_T⁻¹r from one factorisation and one solve.
    if (!parameter_columns(/*newton_step=*/true)) return false;
    z_ = u_ + du_;
    residual(tracked, z_);
    double newton = 0.0;
    for (int d = 0; d < dofs; d += 3)
      newton = std::max(newton, du_.segment<2>(d).cwiseAbs().maxCoeff());
    // The Tukey weights are read off the linearised misfit only where the linearisation is good
    // (the Newton part of the step below 0.05 px); before, plain least squares. Weighting from
    // the start locked onto a fit that left most nodes out (thin cantilever, frame 25: 1.0 px RMS
    // and 7.7 % load error, where the nested fit has 0.22 px and 2.5 %; 0.01 px gives the same).
    constexpr double kRobustBelowPx = 0.05;
    if (!step(newton < kRobustBelowPx, /*scaled_ridge=*/true)) return false;
    du_.noalias() += columns_.leftCols(p) * dq_.head(p);
    double change = 0.0;
    for (int d = 0; d < dofs; d += 3)
      change = std::max(change, du_.segment<2>(d).cwiseAbs().maxCoeff());
    if (!std::isfinite(change)) return false;
    if (change > kMaxStepPx) {
      du_ *= kMaxStepPx / change;
      dq_.head(p) *= kMaxStepPx / change;
    }
    u_ += du_;
    q_.head(p) += dq_.head(p);
    // The Newton part was below the tolerance: the state was an equilibrium of its loads, and the
    // step's linearised equilibrium is one to second order in the step.
    const bool at_equilibrium = newton < kConvergedPx;
    if (change < kConvergedPx || (at_equilibrium && it + 1 == 2 * options_.max_iterations)) {
      residual(tracked, u_);
      loads_prev_.setZero();
      add_loads(loads_prev_, 1.0);
      *equilibrium = true;
      return change < kConvergedPx;
    }
  }
  return false;
}

bool LoadFit::nested(const Eigen::Ref<const Eigen::VectorXd>& tracked, int* iterations,
                     bool* equilibrium) {
  const int p = params_ + base_;
  bool ok = false;
  *equilibrium = false;
  for (int it = 0; it < options_.max_iterations; ++it) {
    ++*iterations;
    rhs_.setZero();
    add_loads(rhs_, 1.0);
    take_supports(tracked, u_);  // the fitted follicle angle, when it is a parameter
    const common::StaticSolverSummary s = solver_.solve(rhs_, u_, &loads_prev_);
    if (!s.converged()) {
      // Start over from the unloaded reference next time.
      reset();
      *equilibrium = false;
      return false;
    }
    *equilibrium = true;
    loads_prev_ = rhs_;
    residual(tracked, u_);
    if (ok) break;  // the previous update was negligible: this equilibrium is the answer

    model_.evaluate(u_, nullptr, nullptr, &tangent_);
    if (!parameter_columns(/*newton_step=*/false)) return false;
    if (!step(true, /*scaled_ridge=*/false)) return false;
    change_.noalias() = jacobian_.leftCols(p) * dq_.head(p);
    const double change = change_.cwiseAbs().maxCoeff();
    if (change > kMaxStepPx) dq_.head(p) *= kMaxStepPx / change;
    if (it + 1 == options_.max_iterations && !(change < kConvergedPx)) {
      // Out of iterations: keep the loads of the last equilibrium rather than an update no
      // equilibrium was solved for.
      break;
    }
    q_.head(p) += dq_.head(p);
    ok = change < kConvergedPx;
  }
  return ok;
}

double LoadFit::update_covariance(bool equilibrium) noexcept {
  const int p = params_ + base_;
  auto C = covariance_.topLeftCorner(p, p);
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  // Weighted squared misfit over the weighted count of measured coordinates (node 0's fitted
  // support dofs are not measurements), less the parameters.
  double misfit = 0.0, measured = -weights_[0] * base_;
  for (int i = 0; i < n_; ++i) {
    misfit += weights_[i] * residual_.segment<3>(3 * i).squaredNorm();
    measured += 3.0 * weights_[i];
  }
  const double dof = measured - p;
  if (!equilibrium || !(dof >= 1.0)) {
    C.setConstant(kNaN);
    return kNaN;
  }
  const double variance = misfit / dof;
  // N⁻¹ M N⁻¹ with M = (WJ)ᵀ(WJ) = Jᵀ W² J: N⁻¹ M, turned (M and N are symmetric), N⁻¹ again.
  // ldlt_ holds N from the last step, at the answer to the stopping rule.
  auto WJ = weighted_jacobian_.leftCols(p);
  auto S = sandwich_.topLeftCorner(p, p);
  S.noalias() = WJ.transpose() * WJ;
  // The held supports of node 0 (fixed, not fitted) take the tracked first node's noisy values:
  // each moves the equilibrium by −K_ff⁻¹ K_f,d (at the loads held), the tracked nodes by g_d,
  // and the parameters by −N⁻¹ (WJ)ᵀ g_d. Their columns per unit arc (rotations as arcs, like
  // the measurements), so each carries the same σ.
  const auto& fixed = model_.fixed_mask();
  int held = 0;
  for (int d = 0; d < 3; ++d) {
    if (!fixed[d] || std::find(base_dofs_, base_dofs_ + base_, d) != base_dofs_ + base_) continue;
    auto z = support_columns_.col(held++);
    z.setZero();
    z.segment<3>(3) = -base_coupling_.col(d) / (d == 2 ? rotation_scale_ : 1.0);
  }
  if (held > 0) {
    auto G = support_jacobian_.leftCols(held);
    factor_.solve_columns_in_place(support_columns_.leftCols(held));
    for (int j = 0; j < held; ++j) {
      const auto z = support_columns_.col(j);
      for (int i = 0; i < n_; ++i) {
        G.block<2, 1>(3 * i, j) = z.segment<2>(3 * parts_ * i);
        G(3 * i + 2, j) = rotation_scale_ * z[3 * parts_ * i + 2];
      }
      G.block<3, 1>(0, j).setZero();  // node 0's own misfit: held exactly, or fitted
    }
    auto T = support_sensitivity_.topLeftCorner(p, held);
    T.noalias() = WJ.transpose() * G;
    S.noalias() += T * T.transpose();
  }
  ldlt_.solveInPlace(S);
  C = S.transpose();
  ldlt_.solveInPlace(C);
  C *= variance;
  return std::sqrt(variance);
}

void LoadFit::consistent_loads(const Eigen::Ref<const Eigen::VectorXd>& tracked,
                               const double* fractions, int count) noexcept {
  const Eigen::Matrix2Xd& X = model_.rest_positions();
  const int last = model_.num_nodes() - 1;
  for (int k = 0; k < count; ++k) {
    auto& c = consistent_[k];
    c.fill(0.0);
    const int a = points_[k];
    const Eigen::Vector2d d(directions_[2 * k], directions_[2 * k + 1]);
    const double xi = a < last ? std::clamp(fractions[k], 0.0, 1.0) : 0.0;
    if (!(xi > 0.0)) {
      c[0] = d.x();
      c[1] = d.y();
      continue;
    }
    // The element's axes: the tracked chord of the coarse element it lies in.
    const int e = std::min(a / parts_, n_ - 2);
    const Eigen::Vector2d chord = X.col(parts_ * (e + 1)) + tracked.segment<2>(3 * (e + 1)) -
                                  X.col(parts_ * e) - tracked.segment<2>(3 * e);
    const Eigen::Vector2d t = chord.normalized(), n(-t.y(), t.x());
    const double along = d.dot(t), across = d.dot(n);
    const double l = (X.col(a + 1) - X.col(a)).norm();
    const double xi2 = xi * xi, xi3 = xi2 * xi;
    const double n1 = 1.0 - 3.0 * xi2 + 2.0 * xi3, n3 = 3.0 * xi2 - 2.0 * xi3;
    const Eigen::Vector2d fa = (1.0 - xi) * along * t + n1 * across * n;
    const Eigen::Vector2d fb = xi * along * t + n3 * across * n;
    c[0] = fa.x();
    c[1] = fa.y();
    c[2] = across * l * (xi - 2.0 * xi2 + xi3);
    c[3] = fb.x();
    c[4] = fb.y();
    c[5] = across * l * (xi3 - xi2);
  }
}

LoadFitSummary LoadFit::fit(const Eigen::Ref<const Eigen::VectorXd>& tracked, const int* points,
                            int count, const double* directions, const double* fractions) noexcept {
  LoadFitSummary summary;
  points_ = points;
  directions_ = directions;
  fractional_ = fractions != nullptr && directions != nullptr;
  if (fractional_)
    consistent_loads(tracked, fractions, std::clamp(count, 0, options_.max_load_points));
  pp_ = directions ? 1 : per_point_;
  params_ = pp_ * std::clamp(count, 0, options_.max_load_points);
  if (params_ == 0) return summary;
  // The follicle angle's parameter follows the loads': carry it over from the last call, whose
  // load count may have differed.
  for (int k = 0; k < base_; ++k) q_[params_ + k] = base_offsets_[base_dofs_[k]];
  u_backup_ = u_;
  q_backup_ = q_;
  int iterations = 0;
  bool coupled_equilibrium = false;
  bool ok = options_.coupled && coupled(tracked, &iterations, &coupled_equilibrium);
  bool equilibrium = ok;
  summary.coupled = ok;
  if (!ok && coupled_equilibrium) {
    // Out of iterations at an equilibrium of its loads (still creeping along the valley where a
    // load and a turn of the follicle look alike, by ~1e-2 px a step): an answer, not converged.
    // The nested fallback from the last call's state, far from this pose, failed there and left
    // a contact frame without a load (tests/rt/test_load_fit_elastica.cpp).
    equilibrium = true;
    summary.coupled = true;
  } else if (!ok) {
    if (options_.coupled) {
      u_ = u_backup_;
      q_ = q_backup_;
      take_supports(tracked, u_);
    }
    iterations = 0;
    ok = nested(tracked, &iterations, &equilibrium);
  }
  for (int k = 0; k < base_; ++k) base_offsets_[base_dofs_[k]] = q_[params_ + k];
  summary.converged = ok;
  summary.equilibrium = equilibrium;
  summary.iterations = iterations;
  summary.rms_px = std::sqrt(residual_.squaredNorm() / n_);
  summary.noise_px = update_covariance(equilibrium);
  return summary;
}

}  // namespace sinew::rt
