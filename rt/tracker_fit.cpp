// Tracker: the Newton fit of one repetition: the model's sample points and their Jacobians, the
// residuals with their robust scale, the image and snake terms, the Newton step and the bending
// reference force.
#include "rt/tracker.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "rt/centreline.hpp"
#include "rt/detail/order_statistic.hpp"
#include "rt/detail/solver_options.hpp"

namespace sinew::rt {

CentrelinePoint Tracker::centreline(int element, double xi) const {
  const Eigen::Vector2d X1 = model_.rest_positions().col(element);
  const common::Vector6d ue = u_.segment<6>(3 * element);
  if (options_.model == TrackerModel::kBeam) {
    return hermite_centreline(X1, model_.element(element), node_tangents_.col(element),
                              node_tangents_.col(element + 1), ue, xi);
  }
  // The snake is a polyline: straight chords between the nodes.
  CentrelinePoint p;
  const Eigen::Vector2d x1 = X1 + ue.segment<2>(0);
  const Eigen::Vector2d x2 = X1 + model_.element(element).chord + ue.segment<2>(3);
  p.position = (1.0 - xi) * x1 + xi * x2;
  Eigen::Vector2d t = x2 - x1;
  const double norm = t.norm();
  t = norm > 0 ? Eigen::Vector2d(t / norm) : Eigen::Vector2d(1.0, 0.0);
  p.normal = Eigen::Vector2d(-t.y(), t.x());
  p.jacobian.setZero();
  p.jacobian(0, 0) = p.jacobian(1, 1) = 1.0 - xi;
  p.jacobian(0, 3) = p.jacobian(1, 4) = xi;
  return p;
}

bool Tracker::points_current(bool normals, bool jacobians) const {
  // Bitwise: a state equal only in value (−0 and +0) is evaluated again.
  return (points_normals_ || !normals) && (points_jacobians_ || !jacobians) &&
         std::memcmp(u_.data(), u_points_.data(), sizeof(double) * u_.size()) == 0;
}

void Tracker::evaluate_points(bool normals, bool jacobians) {
  u_points_ = u_;  // same size: no allocation
  points_normals_ = normals;
  points_jacobians_ = jacobians;
  if (options_.model != TrackerModel::kBeam) {
    points_normals_ = points_jacobians_ = true;
    for (std::size_t k = 0; k < sample_points_.size(); ++k) {
      const CentrelinePoint c = centreline(sample_points_[k].element, sample_points_[k].xi);
      ModelPoint& p = points_[k];
      p.position = c.position;
      p.normal = c.normal;
      p.h00 = c.jacobian(0, 0);
      p.h01 = c.jacobian(0, 3);
      p.dc_dtheta1 = c.jacobian.col(2);
      p.dc_dtheta2 = c.jacobian.col(5);
    }
    return;
  }
  int prepared = -1;
  HermiteElement h;
  for (std::size_t k = 0; k < sample_points_.size(); ++k) {
    const int e = sample_points_[k].element;
    if (e != prepared) {
      // Elements come in order (the end points last): consecutive ones share a node's tangent.
      const HermiteElement previous = h;
      h = hermite_element(model_.rest_positions().col(e), model_.element(e), node_tangents_.col(e),
                          node_tangents_.col(e + 1), u_.segment<6>(3 * e),
                          e == prepared + 1 && prepared >= 0 ? &previous : nullptr);
      prepared = e;
    }
    const HermiteBasis& b = sample_points_[k].basis;
    ModelPoint& p = points_[k];
    p.position = hermite_position(h, b);
    if (normals) p.normal = hermite_normal(h, b);
    if (jacobians) {
      p.h00 = b.h00;
      p.h01 = b.h01;
      hermite_rotation_derivatives(h, b, &p.dc_dtheta1, &p.dc_dtheta2);
    }
  }
}

double Tracker::residuals() {
  const int K = options_.max_candidates;
  std::size_t valid = 0;
  // With a zero half width every line expects its feature on the curve itself (expected_point
  // adds 0·n): a Newton step needs no normals, and skips a square root and a division per point.
  const bool on_curve = options_.half_width_px == 0.0;
  if (!points_current(/*normals=*/!on_curve, /*jacobians=*/true)) {
    evaluate_points(/*normals=*/!on_curve, /*jacobians=*/true);
  }
  for (std::size_t l = 0; l < lines_.size(); ++l) {
    const SearchLine& line = lines_[l];
    const ModelPoint& p = points_[line.point];
    if (l == 0 || lines_[l - 1].point != line.point) {
      // d = (observation − model)·n₀, so ∂d/∂u = −n₀ᵀ ∂c/∂u (the normal's own variation is
      // second order at the fit). The lines of a point share it; add_image_term reads the first's.
      // Written on the structure ∂c/∂u_e = [h00·I, ∂c/∂θ₁, h01·I, ∂c/∂θ₂]: the full 2x6
      // product's terms without its zero ones (the same rows, up to the sign of a zero entry,
      // which add_image_term's sums from +0 do not keep).
      const Eigen::Vector2d& n = line.normal;
      jacobian_rows_[l] << -(n.x() * p.h00), -(n.y() * p.h00), -n.dot(p.dc_dtheta1),
          -(n.x() * p.h01), -(n.y() * p.h01), -n.dot(p.dc_dtheta2);
    }
    residual_[l] = kNaN;
    strength_[l] = 0.0f;
    if (line.num_candidates == 0) continue;
    Eigen::Vector2d direction;
    const Eigen::Vector2d model_point = on_curve ? p.position : expected_point(line, p, &direction);
    const double model_offset = (model_point - line.centre).dot(line.normal);
    double best = std::numeric_limits<double>::infinity();
    // Candidates are sorted strongest first. In a frame's first repetition, when the model may
    // still be far off, the strongest response wins; afterwards the one nearest the model.
    // Ends always take the nearest: beyond an object's end the strongest step is often another
    // object (a holder, the image border).
    const bool strongest = strongest_candidate_ && line.end == 0;
    float best_strength = 0.0f;
    for (int c = 0; c < (strongest ? 1 : line.num_candidates); ++c) {
      const double d = candidates_[l * K + c].offset - model_offset;
      if (std::abs(d) < std::abs(best)) {
        best = d;
        best_strength = candidates_[l * K + c].strength;
      }
    }
    residual_[l] = static_cast<float>(best);
    strength_[l] = best_strength;
    sorted_[valid++] = static_cast<float>(std::abs(best));
  }
  cutoff_ = 0.0;
  if (valid == 0) return 0.0;
  // σ = max(1.4826·median, min_sigma_px) is the floor exactly when more than half of the |d| give
  // at most the floor (1.4826·|d| is monotone in |d|): then the median is not selected. A fit in
  // little noise is there at most of its steps; NaNs leave the decision to the selection.
  const int k = static_cast<int>(valid / 2);
  int at_floor = 0, nan = 0;
  for (std::size_t i = 0; i < valid; ++i) {
    at_floor += 1.4826 * double(sorted_[i]) <= options_.min_sigma_px;
    nan += std::isnan(sorted_[i]);
  }
  double sigma = options_.min_sigma_px;
  if (at_floor <= k || nan > 0) {
    const double median = detail::kth_smallest(sorted_.data(), static_cast<int>(valid), k);
    sigma = std::max(1.4826 * median, options_.min_sigma_px);
  }
  cutoff_ = options_.tukey_c * sigma;
  return cutoff_;
}

double Tracker::object_fraction_at_last_step() const {
  // The end-of-frame test for the object (see track()) on the residuals of the last Newton step,
  // without the pairing of boundaries.
  const double near = std::min(cutoff_, options_.object_residual_px);
  const float threshold = static_cast<float>(options_.min_relative_strength * typical_strength_);
  int strong = 0;
  for (std::size_t l = 0; l < lines_.size(); ++l) {
    strong += std::abs(residual_[l]) < near && strength_[l] >= threshold;
  }
  return lines_.empty() ? 0.0 : double(strong) / double(lines_.size());
}

void Tracker::add_image_term(double cutoff) {
  // Lines of one sample point share their Jacobian row (the same normal at the same point), so
  // their Tukey-weighted terms add up to one rank-1 update (Σw) j jᵀ; an element's updates are
  // summed locally and scattered into the system once. Locally only the blocks the system reads:
  // the block-tridiagonal tangent keeps (e, e), (e+1, e) (the 6x3 `left`) and (e+1, e+1)
  // (rows 1-3 of `right`), not (e, e+1); the snake's dense matrix takes that too (`upper`).
  // `right` has a spare first row so that its column update is the two aligned packets (a₂, a₃),
  // (a₄, a₅) of a = (Σw) j: a padded copy of (a₃, a₄, a₅) was built through memory, and loading
  // it stalled on the store (a third of this function's time).
  const bool snake = options_.model == TrackerModel::kSnake;
  const double inverse_cutoff = 1.0 / cutoff;  // used only where |d| < cutoff
  Eigen::Matrix<double, 6, 3> left;
  Eigen::Matrix<double, 4, 3> right;
  Eigen::Matrix3d upper = Eigen::Matrix3d::Zero();
  common::Vector6d g;
  auto clear = [&]() {
    // Column by column: GCC turns a whole-matrix setZero here into `rep stos`, whose start-up
    // cost was half of the scatter's.
    for (int c = 0; c < 3; ++c) {
      left.col(c).setZero();
      right.col(c).setZero();
    }
    g.setZero();
  };
  clear();
  int element = -1;
  auto scatter = [&]() {
    if (element < 0) return;
    if (snake) {
      snake_matrix_.block<6, 3>(3 * element, 3 * element) += left;
      snake_matrix_.block<3, 3>(3 * element, 3 * element + 3) += upper;
      snake_matrix_.block<3, 3>(3 * element + 3, 3 * element + 3) += right.bottomRows<3>();
      upper.setZero();
    } else {
      tangent_.add_element_lower(element, left, right.bottomRows<3>());
    }
    gradient_.segment<6>(3 * element) += g;
    clear();
  };
  std::size_t l = 0;
  while (l < lines_.size()) {
    const std::size_t first = l;
    double sum_w = 0.0, sum_wd = 0.0;
    // The follicle's face edge is one strong feature, not one of many samples of the object: its
    // robust scale is the distance its search covers, not the normals' (a whisker that slid by
    // more than the normals' cut-off would otherwise never be pulled back).
    const bool follicle = lines_[first].end < 0 && options_.start_end == StartEnd::kDarkRegion;
    const double line_cutoff =
        follicle ? std::max(cutoff, double(options_.first_search_range_px)) : cutoff;
    const double line_inverse_cutoff = follicle ? 1.0 / line_cutoff : inverse_cutoff;
    for (; l < lines_.size() && lines_[l].point == lines_[first].point; ++l) {
      const float d = residual_[l];
      if (!(std::abs(d) < line_cutoff)) continue;  // NaN or an outlier: weight 0
      const double r = d * line_inverse_cutoff;
      const double w = observation_weight_ * (1.0 - r * r) * (1.0 - r * r);  // Tukey
      sum_w += w;
      sum_wd += w * d;
    }
    if (sum_w == 0.0) continue;
    if (lines_[first].end != 0) {
      sum_w *= options_.end_weight;
      sum_wd *= options_.end_weight;
    }
    if (lines_[first].element != element) {
      scatter();
      element = lines_[first].element;
    }
    const common::Vector6d& j = jacobian_rows_[first];
    const common::Vector6d a = sum_w * j;
    left.noalias() += a * j.head<3>().transpose();
    right.noalias() += a.segment<4>(2) * j.tail<3>().transpose();  // row 0: a₂ j, unused
    if (snake) upper.noalias() += a.head<3>() * j.tail<3>().transpose();
    g += sum_wd * j;
  }
  scatter();
}

void Tracker::add_snake_term() {
  // E = w_s Σ_e (|d_e| − L₀)² + w_b Σ_i |Δ²x_i − Δ²X_i|² (seed 000 §5.2), positions only.
  const int n = model_.num_nodes();
  const double ws = options_.snake_stretch_weight, wb = options_.snake_bend_weight;
  for (int e = 0; e + 1 < n; ++e) {
    const Eigen::Vector2d d =
        model_.element(e).chord + u_.segment<2>(3 * e + 3) - u_.segment<2>(3 * e);
    const double len = std::max(d.norm(), 1e-12);
    const double L0 = model_.element(e).length;
    const Eigen::Vector2d g = d / len;
    const Eigen::Vector2d grad = 2.0 * ws * (len - L0) * g;
    // Hessian of (|d| − L₀)²: 2 g gᵀ + 2 (|d| − L₀)/|d| (I − g gᵀ), the second part clamped at 0.
    Eigen::Matrix2d H = 2.0 * ws * g * g.transpose();
    if (len > L0)
      H += 2.0 * ws * (len - L0) / len * (Eigen::Matrix2d::Identity() - g * g.transpose());
    gradient_.segment<2>(3 * e) -= grad;
    gradient_.segment<2>(3 * e + 3) += grad;
    snake_matrix_.block<2, 2>(3 * e, 3 * e) += H;
    snake_matrix_.block<2, 2>(3 * e + 3, 3 * e + 3) += H;
    snake_matrix_.block<2, 2>(3 * e, 3 * e + 3) -= H;
    snake_matrix_.block<2, 2>(3 * e + 3, 3 * e) -= H;
  }
  const double coeff[3] = {1.0, -2.0, 1.0};
  for (int i = 1; i + 1 < n; ++i) {
    // Δ²u (the reference's Δ²X cancels in Δ²x − Δ²X).
    const Eigen::Vector2d b =
        u_.segment<2>(3 * i + 3) - 2.0 * u_.segment<2>(3 * i) + u_.segment<2>(3 * i - 3);
    for (int a = 0; a < 3; ++a) {
      gradient_.segment<2>(3 * (i - 1 + a)) += 2.0 * wb * coeff[a] * b;
      for (int c = 0; c < 3; ++c) {
        snake_matrix_.block<2, 2>(3 * (i - 1 + a), 3 * (i - 1 + c)).diagonal().array() +=
            2.0 * wb * coeff[a] * coeff[c];
      }
    }
  }
}

bool Tracker::newton_step() {
  const double cutoff = residuals();
  const int n = model_.num_nodes();
  if (options_.model == TrackerModel::kBeam) {
    Eigen::Ref<Eigen::VectorXd> g(gradient_);
    model_.evaluate(u_, nullptr, &g, &tangent_);
    gradient_ -= p_ref_;  // elastic forces relative to this repetition's start
    add_image_term(cutoff);
    for (int i = 0; i < n; ++i) {
      tangent_.diagonal(i)(0, 0) += damping_translation_;
      tangent_.diagonal(i)(1, 1) += damping_translation_;
      tangent_.diagonal(i)(2, 2) += damping_rotation_;
    }
    const auto& fixed = model_.fixed_mask();
    tangent_.apply_fixed_dofs(fixed);
    for (Eigen::Index k = 0; k < gradient_.size(); ++k) {
      if (fixed[k]) gradient_[k] = 0.0;
    }
    du_ = -gradient_;
    if (options_.dense_solve) {
      // The seed's dense solve (for comparisons): the same matrix, factorised as a full one.
      dense_tangent_.setZero();
      for (int i = 0; i < n; ++i) {
        dense_tangent_.block<3, 3>(3 * i, 3 * i) = tangent_.diagonal(i);
        if (i + 1 < n) {
          dense_tangent_.block<3, 3>(3 * i + 3, 3 * i) = tangent_.lower(i);
          dense_tangent_.block<3, 3>(3 * i, 3 * i + 3) = tangent_.lower(i).transpose();
        }
      }
      dense_ldlt_.compute(dense_tangent_);
      if (dense_ldlt_.info() != Eigen::Success) return false;
      dense_ldlt_.solveInPlace(du_);
    } else {
      if (!ldlt_.factor(tangent_)) return false;
      ldlt_.solve_in_place(du_);
    }
  } else {
    snake_matrix_.setZero();
    gradient_.setZero();
    add_snake_term();
    gradient_ -= p_ref_;
    add_image_term(cutoff);
    snake_matrix_.diagonal().array() += damping_translation_;
    for (Eigen::Index k = 0; k < gradient_.size(); ++k) {
      if (!snake_fixed_[k]) continue;
      gradient_[k] = 0.0;
      snake_matrix_.row(k).setZero();
      snake_matrix_.col(k).setZero();
      snake_matrix_(k, k) = 1.0;
    }
    snake_ldlt_.compute(snake_matrix_);
    if (snake_ldlt_.info() != Eigen::Success) return false;
    du_ = -gradient_;
    snake_ldlt_.solveInPlace(du_);
  }
  if (!du_.allFinite()) return false;
  u_ += du_;
  return true;
}

void Tracker::internal_force_at_start() {
  bending_reference_force(p_ref_);
}

void Tracker::bending_reference_force(Eigen::VectorXd& p_ref) const {
  // Only the bending part is taken relative to the repetition's start: axial and shear strains stay
  // measured from the reference, so the image forces can bend the beam all the way onto the data
  // but cannot stretch it along its axis, where edges give no information.
  p_ref.setZero();
  if (options_.model == TrackerModel::kBeam) {
    // The bending part of p is L₀·M·∂κ/∂u = M·(−e_θ₁ + e_θ₂) per element.
    for (int e = 0; e < model_.num_elements(); ++e) {
      const double kappa = common::beam_curvature(model_.element(e), u_.segment<6>(3 * e));
      const common::BeamSection& section = model_.description().sections[e];
      const double M0 =
          model_.description().prestress.empty() ? 0.0 : model_.description().prestress[e].M0;
      const double M = (1.0 - options_.bending_memory) * (M0 + section.EI * kappa);
      p_ref[3 * e + 2] -= M;
      p_ref[3 * e + 5] += M;
    }
  } else {
    // Snake: the bending term's gradient at the start (the stretching term stays absolute).
    const int n = model_.num_nodes();
    const double coeff[3] = {1.0, -2.0, 1.0};
    for (int i = 1; i + 1 < n; ++i) {
      const Eigen::Vector2d b =
          u_.segment<2>(3 * i + 3) - 2.0 * u_.segment<2>(3 * i) + u_.segment<2>(3 * i - 3);
      for (int a = 0; a < 3; ++a) {
        p_ref.segment<2>(3 * (i - 1 + a)) +=
            (1.0 - options_.bending_memory) * 2.0 * options_.snake_bend_weight * coeff[a] * b;
      }
    }
  }
}

double Tracker::rms_node_distance(const Eigen::VectorXd& a, const Eigen::VectorXd& b) const {
  double sum = 0.0;
  for (int i = 0; i < model_.num_nodes(); ++i) {
    sum += (a.segment<2>(3 * i) - b.segment<2>(3 * i)).squaredNorm();
  }
  return std::sqrt(sum / model_.num_nodes());
}

double Tracker::max_node_distance(const Eigen::VectorXd& a, const Eigen::VectorXd& b) const {
  // The largest squared distance, then one square root: the square root is monotone and correctly
  // rounded, so this is the largest of the distances exactly.
  double m = 0.0;
  for (int i = 0; i < model_.num_nodes(); ++i) {
    m = std::max(m, (a.segment<2>(3 * i) - b.segment<2>(3 * i)).squaredNorm());
  }
  return std::sqrt(m);
}

double Tracker::max_node_translation(const Eigen::VectorXd& du) const {
  double m = 0.0;  // as in max_node_distance
  for (int i = 0; i < model_.num_nodes(); ++i) m = std::max(m, du.segment<2>(3 * i).squaredNorm());
  return std::sqrt(m);
}

}  // namespace sinew::rt
