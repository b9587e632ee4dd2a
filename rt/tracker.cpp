#include "rt/tracker.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>

#include "common/detail/field_error.hpp"
#include "rt/centreline.hpp"
#include "rt/detail/order_statistic.hpp"
#include "rt/detail/solver_options.hpp"

namespace sinew::rt {

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

std::string field_error(const char* name, double value, const char* constraint) {
  return common::detail::field_error("options.", name, value, constraint);
}

// The verification model: the tracked beam itself when its fixed dofs constrain rigid motion,
// otherwise (free beams) the same beam clamped at node 0, which is then held at its tracked pose.
common::BeamDescription verification_description(const common::BeamDescription& beam) {
  common::BeamDescription d = beam;
  const common::BeamModel probe(beam);
  if (probe.valid() && !probe.rigid_motions_constrained()) d.clamp(0);
  return d;
}

}  // namespace

std::optional<std::string> TrackerOptions::validate() const {
  if ((observation == ObservationMode::kEdge || observation == ObservationMode::kEdgeMap) &&
      !(half_width_px > 0.0)) {
    return field_error("half_width_px", half_width_px, "must be > 0 in edge and edge-map modes");
  }
  if (samples_per_element < 1 || samples_per_element > 256) {
    return field_error("samples_per_element", samples_per_element, "must be in [1, 256]");
  }
  if (search_range_px < 1 || search_range_px > 200) {
    return field_error("search_range_px", search_range_px, "must be in [1, 200]");
  }
  if (first_search_range_px < search_range_px || first_search_range_px > 200) {
    return field_error("first_search_range_px", first_search_range_px,
                       "must be in [search_range_px, 200]");
  }
  if (max_candidates < 1 || max_candidates > 16) {
    return field_error("max_candidates", max_candidates, "must be in [1, 16]");
  }
  if (!(min_strength > 0.0)) return field_error("min_strength", min_strength, "must be > 0");
  if (!(ridge_min_background >= 0.0)) {
    return field_error("ridge_min_background", ridge_min_background, "must be >= 0");
  }
  if (!(end_weight > 0.0)) return field_error("end_weight", end_weight, "must be > 0");
  if (!(dark_region_min_step > 0.0)) {
    return field_error("dark_region_min_step", dark_region_min_step, "must be > 0");
  }
  if (line_surround_px < 0 || line_surround_px > 50) {
    return field_error("line_surround_px", line_surround_px, "must be in [0, 50]");
  }
  if (band_px < 0 || band_px > 10) return field_error("band_px", band_px, "must be in [0, 10]");
  if (!(image_stiffness > 0.0)) {
    return field_error("image_stiffness", image_stiffness, "must be > 0");
  }
  if (!(min_image_length_px >= 0.0)) {
    return field_error("min_image_length_px", min_image_length_px, "must be >= 0");
  }
  if (!(bending_memory >= 0.0 && bending_memory < 1.0)) {
    return field_error("bending_memory", bending_memory, "must be in [0, 1)");
  }
  if (max_repetitions < 1) return field_error("max_repetitions", max_repetitions, "must be >= 1");
  if (max_newton_iterations < 1) {
    return field_error("max_newton_iterations", max_newton_iterations, "must be >= 1");
  }
  if (!(convergence_px > 0.0)) return field_error("convergence_px", convergence_px, "must be > 0");
  if (!(research_px >= 0.0)) return field_error("research_px", research_px, "must be >= 0");
  if (!(predictable_px >= 0.0)) {
    return field_error("predictable_px", predictable_px, "must be >= 0");
  }
  if (!(tukey_c > 0.0)) return field_error("tukey_c", tukey_c, "must be > 0");
  if (!(min_sigma_px > 0.0)) return field_error("min_sigma_px", min_sigma_px, "must be > 0");
  if (!(object_residual_px > 0.0)) {
    return field_error("object_residual_px", object_residual_px, "must be > 0");
  }
  if (!(min_relative_strength >= 0.0 && min_relative_strength < 1.0)) {
    return field_error("min_relative_strength", min_relative_strength, "must be in [0, 1)");
  }
  if (!(min_inlier_fraction >= 0.0 && min_inlier_fraction <= 1.0)) {
    return field_error("min_inlier_fraction", min_inlier_fraction, "must be in [0, 1]");
  }
  if (verify_load_steps < 1) {
    return field_error("verify_load_steps", verify_load_steps, "must be >= 1");
  }
  if (!(snake_stretch_weight >= 0.0)) {
    return field_error("snake_stretch_weight", snake_stretch_weight, "must be >= 0");
  }
  if (!(snake_bend_weight >= 0.0)) {
    return field_error("snake_bend_weight", snake_bend_weight, "must be >= 0");
  }
  if (load_fit_subdivisions < 1) {
    return field_error("load_fit_subdivisions", load_fit_subdivisions, "must be >= 1");
  }
  if (max_load_fit_iterations < 1) {
    return field_error("max_load_fit_iterations", max_load_fit_iterations, "must be >= 1");
  }
  return std::nullopt;
}

const char* to_string(FrameStatus status) {
  switch (status) {
    case FrameStatus::kOk:
      return "ok";
    case FrameStatus::kLost:
      return "lost";
    case FrameStatus::kNotConverged:
      return "not_converged";
  }
  return "unknown";
}

Tracker::Tracker(common::BeamDescription beam, TrackerOptions options, std::vector<int> load_nodes)
    : model_(beam),
      options_(options),
      load_nodes_(std::move(load_nodes)),
      verify_model_(verification_description(beam)),
      verify_solver_(verify_model_, detail::solver_options(options.verify_load_steps, 25, 10)),
      verify_solver_warm_(verify_model_, detail::solver_options(8, 25, 10)),
      verify_solver_direct_(verify_model_, detail::solver_options(1, 20, 0)),
      fit_points_(load_nodes_.size()) {
  if (!model_.valid()) {
    error_ = model_.error();
    return;
  }
  if (auto err = options_.validate()) {
    error_ = *err;
    return;
  }
  const int n = model_.num_nodes();
  for (std::size_t k = 0; k < load_nodes_.size(); ++k) {
    const int node = load_nodes_[k];
    if (node < 0 || node >= n) {
      error_ = "load_nodes[" + std::to_string(k) + "] = " + std::to_string(node) +
               " is out of range (the beam has " + std::to_string(n) + " nodes)";
      return;
    }
    for (std::size_t j = 0; j < k; ++j) {
      if (load_nodes_[j] == node) {
        error_ =
            "load_nodes[" + std::to_string(k) + "] = " + std::to_string(node) + " is listed twice";
        return;
      }
    }
  }
  if (load_nodes_.size() > 8) {
    error_ = "load_nodes has " + std::to_string(load_nodes_.size()) + " nodes; at most 8";
    return;
  }
  if (!load_nodes_.empty() && !model_.rigid_motions_constrained()) {
    error_ =
        "load_nodes needs fixed dofs that hold the beam (e.g. a clamped node): a free beam "
        "cannot carry loads at a few nodes in equilibrium";
    return;
  }

  sides_ = options_.observation == ObservationMode::kEdge ||
                   options_.observation == ObservationMode::kEdgeMap
               ? 2
               : 1;
  profile_search_.mode = options_.observation;
  // Sizes the scratch for the widest search: after a lost frame, twice the first range.
  profile_search_.range_px = std::min(2 * options_.first_search_range_px, 200);
  profile_search_.max_candidates = options_.max_candidates;
  profile_search_.min_strength = static_cast<float>(options_.min_strength);
  profile_search_.band_px = options_.band_px;
  profile_search_.min_background = static_cast<float>(options_.ridge_min_background);
  profile_search_.line_surround_px =
      options_.line_surround_px > 0
          ? options_.line_surround_px
          : std::max(2, static_cast<int>(std::lround(options_.half_width_px + 1.5)));
  if (options_.observation != ObservationMode::kEdge && options_.half_width_px <= 0.0) {
    profile_search_.line_surround_px =
        options_.line_surround_px > 0 ? options_.line_surround_px : 3;
  }

  const int elements = model_.num_elements();
  const int per_element = options_.samples_per_element * sides_;
  node_tangents_ = polyline_node_tangents(model_.rest_positions());
  const auto& fixed_mask = model_.fixed_mask();
  const bool start_free = options_.observe_ends && !fixed_mask[0] && !fixed_mask[1];
  const bool end_free = options_.observe_ends &&
                        options_.observation != ObservationMode::kDarkRidge &&
                        !fixed_mask[3 * (n - 1)] && !fixed_mask[3 * (n - 1) + 1];
  lines_.resize(static_cast<std::size_t>(elements) * per_element + start_free + end_free);
  std::size_t l = 0;
  double stiffness = 0.0, mean_length = 0.0;
  const double min_image_length = options_.min_image_length_px > 0.0 ? options_.min_image_length_px
                                                                     : 4.0 * options_.half_width_px;
  for (int e = 0; e < elements; ++e) {
    for (int s = 0; s < options_.samples_per_element; ++s) {
      const float xi = static_cast<float>((s + 0.5) / options_.samples_per_element);
      sample_points_.push_back({e, xi});
      for (int side = 0; side < sides_; ++side) {
        SearchLine& line = lines_[l++];
        line.element = e;
        line.xi = xi;
        line.side = sides_ == 1 ? 0.0f : (side == 0 ? -1.0f : 1.0f);
        line.point = static_cast<int>(sample_points_.size()) - 1;
      }
    }
    const double L0 = model_.element(e).length;
    // 12·EI/ℓ³·(L₀/ℓ) per element: 12·EI/L₀³ when ℓ = L₀, otherwise 12·EI/ℓ⁴ per unit length.
    const double ell = std::max(L0, min_image_length);
    stiffness += 12.0 * model_.description().sections[e].EI / (ell * ell * ell) * (L0 / ell);
    mean_length += L0;
  }
  if (start_free) {
    sample_points_.push_back({0, 0.0});
    lines_[l].element = 0;
    lines_[l].xi = 0.0f;
    lines_[l].point = static_cast<int>(sample_points_.size()) - 1;
    lines_[l++].end = -1;
  }
  if (end_free) {
    sample_points_.push_back({elements - 1, 1.0});
    lines_[l].element = elements - 1;
    lines_[l].xi = 1.0f;
    lines_[l].point = static_cast<int>(sample_points_.size()) - 1;
    lines_[l++].end = 1;
  }
  points_.resize(sample_points_.size());
  stiffness /= elements;
  mean_length /= elements;
  observation_weight_ = options_.model == TrackerModel::kSnake
                            ? 1.0
                            : options_.image_stiffness * stiffness / per_element;
  damping_translation_ = 1e-9 * observation_weight_ * per_element;
  damping_rotation_ = damping_translation_ * mean_length * mean_length;

  candidates_.resize(lines_.size() * options_.max_candidates);
  residual_.assign(lines_.size(), kNaN);
  strength_.assign(lines_.size(), 0.0f);
  sorted_.resize(lines_.size());
  jacobian_rows_.resize(lines_.size());
  // Profile and response of the widest search: both boundaries of a sample at ±half width.
  const int widest = 2 * (static_cast<int>(std::lround(std::max(0.0, options_.half_width_px))) +
                          profile_search_.range_px + profile_search_.line_surround_px + 2) +
                     1;
  scratch_.resize(2 * std::max(widest, profile_search_.scratch_size() / 2));
  const int dofs = model_.num_dofs();
  for (Eigen::VectorXd* v :
       {&u_, &u_prev1_, &u_prev2_, &u_predicted_, &u_start_, &p_ref_, &gradient_, &du_, &forces_,
        &fitted_loads_, &u_verify_, &verify_loads_prev_, &verify_previous_state_,
        &verify_previous_forces_, &verify_backup_, &u_searched_, &p_next_}) {
    v->setZero(dofs);
  }
  tangent_.resize(n);
  ldlt_.resize(n);
  if (options_.dense_solve) {
    dense_tangent_.setZero(dofs, dofs);
    dense_ldlt_ = Eigen::LDLT<Eigen::MatrixXd>(dofs);
  }
  if (options_.model == TrackerModel::kSnake) {
    snake_matrix_.setZero(dofs, dofs);
    snake_ldlt_ = Eigen::LDLT<Eigen::MatrixXd>(dofs);
    snake_fixed_ = model_.fixed_mask();
    for (int i = 0; i < n; ++i) snake_fixed_[3 * i + 2] = 1;  // a polyline has no rotations
  }
  if (static_cast<int>(sorted_.size()) < n) sorted_.resize(n);
  if (!load_nodes_.empty()) {
    LoadFitOptions lo;
    lo.max_iterations = options_.max_load_fit_iterations;
    lo.fit_moments = options_.fit_moments;
    lo.subdivisions = options_.load_fit_subdivisions;
    lo.coupled = options_.coupled_load_fit;
    lo.max_load_points = static_cast<int>(load_nodes_.size());
    load_fit_.emplace(beam, lo);
    if (!load_fit_->valid()) {
      error_ = load_fit_->error();
      return;
    }
    for (std::size_t k = 0; k < load_nodes_.size(); ++k) {
      fit_points_[k] = load_fit_->fine_node(load_nodes_[k]);
    }
  }
}

void Tracker::reset_motion() noexcept {
  u_prev2_ = u_prev1_;
  last_miss_px_ = std::numeric_limits<double>::infinity();
}

void Tracker::restart_at(const Eigen::Ref<const Eigen::Matrix2Xd>& nodes) noexcept {
  const int n = model_.num_nodes();
  if (nodes.cols() != n) return;
  for (int i = 0; i < n; ++i) {
    u_.segment<2>(3 * i) = nodes.col(i) - model_.rest_positions().col(i);
    // The node's tangent now (central chord) against its reference tangent.
    const Eigen::Vector2d t = nodes.col(std::min(i + 1, n - 1)) - nodes.col(std::max(i - 1, 0));
    const Eigen::Vector2d t0 = node_tangents_.col(i);
    u_[3 * i + 2] = std::atan2(t0.x() * t.y() - t0.y() * t.x(), t0.dot(t));
  }
  u_prev1_ = u_;
  u_prev2_ = u_;
  continue_as_after_a_lost_frame();
}

void Tracker::reject_last_frame() noexcept {
  if (!last_accepted_) return;
  // After an accepted frame u_prev1_ = u_ and u_prev2_ holds the frame before.
  u_ = u_prev2_;
  u_prev1_ = u_prev2_;
  continue_as_after_a_lost_frame();
}

void Tracker::continue_as_after_a_lost_frame() noexcept {
  previous_lost_ = true;
  last_accepted_ = false;
  verify_have_previous_ = false;
  last_miss_px_ = std::numeric_limits<double>::infinity();
}

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

void Tracker::evaluate_points(bool jacobians) {
  if (options_.model != TrackerModel::kBeam) {
    for (std::size_t k = 0; k < sample_points_.size(); ++k) {
      points_[k] = centreline(sample_points_[k].element, sample_points_[k].xi);
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
    points_[k] = hermite_point(h, sample_points_[k].xi, jacobians);
  }
}

EdgePolarity Tracker::measure_polarity(const ImageView& frame) const {
  double inside = 0.0, outside = 0.0;
  int count = 0;
  const double offset = options_.half_width_px + 3.0;
  for (const SearchLine& line : lines_) {
    if (line.side <= 0.0f) continue;  // one sample per position
    const CentrelinePoint p = centreline(line.element, line.xi);
    float centre, plus, minus;
    if (frame.sample(p.position.x(), p.position.y(), &centre) &&
        frame.sample(p.position.x() + offset * p.normal.x(), p.position.y() + offset * p.normal.y(),
                     &plus) &&
        frame.sample(p.position.x() - offset * p.normal.x(), p.position.y() - offset * p.normal.y(),
                     &minus)) {
      inside += centre;
      outside += 0.5 * (plus + minus);
      ++count;
    }
  }
  if (count == 0) return EdgePolarity::kAny;
  const double contrast = (outside - inside) / count;
  if (contrast > options_.min_strength) return EdgePolarity::kDarkObject;
  if (contrast < -options_.min_strength) return EdgePolarity::kBrightObject;
  return EdgePolarity::kAny;
}

Eigen::Vector2d Tracker::expected_point(const SearchLine& line, const CentrelinePoint& p,
                                        Eigen::Vector2d* direction) const {
  if (line.end == 0) {
    *direction = p.normal;
    return p.position + (line.side * options_.half_width_px) * p.normal;
  }
  // The normal is the tangent turned by +90°, so the tangent is (n.y, −n.x).
  *direction = line.end * Eigen::Vector2d(p.normal.y(), -p.normal.x());
  return p.position + options_.half_width_px * *direction;
}

void Tracker::search(const ImageView& frame, int range_px) {
  const int K = options_.max_candidates;
  evaluate_points(/*jacobians=*/false);  // positions and normals; residuals() needs the rest
  ProfileSearch base = profile_search_;
  base.range_px = std::min(range_px, profile_search_.range_px);  // never past the scratch
  // In edge mode the wide first search only has to bring the model near the object's strong
  // boundaries: one pixel row is enough (a third of the samples); the band averaging that fixes
  // the final positions comes after. Thin lines in noise need the band from the start.
  if (range_px > options_.search_range_px && options_.observation == ObservationMode::kEdge) {
    base.band_px = 0;
  }
  const int margin = base.margin();
  // The whole-pixel offset of a line's centre from its sample point (± the rounded half width).
  const int half_width = static_cast<int>(std::lround(options_.half_width_px));
  auto side_offset_px = [&](const SearchLine& line) {
    return line.side > 0.0f ? half_width : line.side < 0.0f ? -half_width : 0;
  };
  float* profile = scratch_.data();
  float* response = scratch_.data() + scratch_.size() / 2;
  // Expected intensity step along the search direction (edge mode): a dark object's +n boundary
  // goes dark → bright, its −n boundary bright → dark.
  auto edge_sign = [&](const SearchLine& line) {
    if (options_.observation != ObservationMode::kEdge) return 0;
    const int sign = line.side > 0 ? 1 : -1;
    return polarity_ == EdgePolarity::kDarkObject     ? sign
           : polarity_ == EdgePolarity::kBrightObject ? -sign
                                                      : 0;
  };
  if (options_.observation == ObservationMode::kEdgeMap) {
    // The seed's observations: the edge pixels nearest the model along each line.
    for (std::size_t j = 0; j < lines_.size(); ++j) {
      SearchLine& line = lines_[j];
      line.centre = expected_point(line, points_[line.point], &line.normal);
      line.num_candidates =
          search_edge_map(frame, line.centre, line.normal, base.range_px, K, &candidates_[j * K]);
    }
    return;
  }
  // Pixels reach the cache a few sample points ahead of their sampling (see prefetch_profile).
  const int reach = (sides_ == 2 ? half_width : 0) + base.range_px + margin;
  constexpr int kPrefetchAhead = 4;
  auto prefetch = [&](std::size_t point) {
    if (point < points_.size()) {
      prefetch_profile(frame, points_[point].position, points_[point].normal, -reach,
                       2 * reach + 2);
    }
  };
  for (int k = 0; k < kPrefetchAhead; ++k) prefetch(k);
  std::size_t l = 0;
  while (l < lines_.size()) {
    SearchLine& line = lines_[l];
    const CentrelinePoint& p = points_[line.point];
    prefetch(line.point + kPrefetchAhead);
    if (line.end != 0) {
      // An end: the object gives way to background going outwards along the tangent.
      line.centre = expected_point(line, p, &line.normal);
      ProfileSearch search = base;
      search.mode = ObservationMode::kEdge;
      const bool dark = options_.observation == ObservationMode::kDarkLine ||
                        options_.observation == ObservationMode::kDarkRidge ||
                        (options_.observation == ObservationMode::kEdge &&
                         polarity_ == EdgePolarity::kDarkObject);
      const bool bright = options_.observation == ObservationMode::kBrightLine ||
                          (options_.observation == ObservationMode::kEdge &&
                           polarity_ == EdgePolarity::kBrightObject);
      search.expected_sign = dark ? 1 : bright ? -1 : 0;
      if (line.end < 0 && options_.start_end == StartEnd::kDarkRegion) {
        // The follicle: intensity falls where the face begins, going outwards from the base.
        search.expected_sign = -1;
        search.min_strength = static_cast<float>(options_.dark_region_min_step);
      }
      line.num_candidates = search_profile(frame, line.centre, line.normal, search, scratch_.data(),
                                           &candidates_[l * K]);
      ++l;
      continue;
    }
    // The lines of one sample point (both boundaries in edge mode) search along the same normal:
    // one profile across the object serves them all (edge mode: 2·(w + range) + 1 samples instead
    // of 2·(2·range + 1), w the half width). Samples sit at whole pixels from the centreline; a
    // line whose centre is not (fractional half width) reports offsets relative to its centre.
    std::size_t last = l;
    while (last + 1 < lines_.size() && lines_[last + 1].point == line.point &&
           lines_[last + 1].end == 0) {
      ++last;
    }
    int lo = std::numeric_limits<int>::max(), hi = std::numeric_limits<int>::min();
    for (std::size_t j = l; j <= last; ++j) {
      lines_[j].centre = expected_point(lines_[j], p, &lines_[j].normal);
      const int c = side_offset_px(lines_[j]);
      lo = std::min(lo, c - base.range_px - margin);
      hi = std::max(hi, c + base.range_px + margin);
    }
    sample_profile(frame, p.position, p.normal, lo, hi - lo + 1, base.band_px, profile);
    for (std::size_t j = l; j <= last; ++j) {
      const double c = lines_[j].side * options_.half_width_px;
      const int ci = side_offset_px(lines_[j]);
      ProfileSearch search = base;
      search.expected_sign = edge_sign(lines_[j]);
      lines_[j].num_candidates = find_candidates(profile, ci - lo, static_cast<float>(c - ci),
                                                 search, response, &candidates_[j * K]);
    }
    l = last + 1;
  }
}

double Tracker::residuals() {
  const int K = options_.max_candidates;
  std::size_t valid = 0;
  evaluate_points();
  for (std::size_t l = 0; l < lines_.size(); ++l) {
    const SearchLine& line = lines_[l];
    const CentrelinePoint& p = points_[line.point];
    if (l == 0 || lines_[l - 1].point != line.point) {
      // d = (observation − model)·n₀, so ∂d/∂u = −n₀ᵀ ∂c/∂u (the normal's own variation is
      // second order at the fit). The lines of a point share it; add_image_term reads the first's.
      jacobian_rows_[l] = -(line.normal.transpose() * p.jacobian).transpose();
    }
    residual_[l] = kNaN;
    strength_[l] = 0.0f;
    if (line.num_candidates == 0) continue;
    Eigen::Vector2d direction;
    const Eigen::Vector2d model_point = expected_point(line, p, &direction);
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
  const double median =
      detail::kth_smallest(sorted_.data(), static_cast<int>(valid), static_cast<int>(valid / 2));
  const double sigma = std::max(1.4826 * median, options_.min_sigma_px);
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
  // summed locally and scattered into the system once.
  const bool snake = options_.model == TrackerModel::kSnake;
  const double inverse_cutoff = 1.0 / cutoff;  // used only where |d| < cutoff
  common::Matrix6d H = common::Matrix6d::Zero();
  common::Vector6d g = common::Vector6d::Zero();
  int element = -1;
  auto scatter = [&]() {
    if (element < 0) return;
    if (snake) {
      snake_matrix_.block<6, 6>(3 * element, 3 * element) += H;
    } else {
      tangent_.add_element(element, H);
    }
    gradient_.segment<6>(3 * element) += g;
    H.setZero();
    g.setZero();
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
    H.noalias() += (sum_w * j) * j.transpose();
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
      const common::BeamStrains h = common::beam_strains(model_.element(e), u_.segment<6>(3 * e));
      const common::BeamSection& section = model_.description().sections[e];
      const double M0 =
          model_.description().prestress.empty() ? 0.0 : model_.description().prestress[e].M0;
      const double M = (1.0 - options_.bending_memory) * (M0 + section.EI * h.kappa);
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
  double m = 0.0;
  for (int i = 0; i < model_.num_nodes(); ++i) {
    m = std::max(m, (a.segment<2>(3 * i) - b.segment<2>(3 * i)).norm());
  }
  return m;
}

FrameSummary Tracker::track(const ImageView& frame) noexcept {
  const auto t0 = std::chrono::steady_clock::now();
  FrameSummary summary;
  auto finish = [&]() {
    summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return summary;
  };
  if (!valid() || !frame.valid()) return finish();

  if (frames_ == 0 && options_.observation == ObservationMode::kEdge) {
    u_.setZero();
    polarity_ =
        options_.polarity == EdgePolarity::kAuto ? measure_polarity(frame) : options_.polarity;
  }
  if (frames_ >= 2 && options_.predict) {
    u_ = 2.0 * u_prev1_ - u_prev2_;
  } else if (frames_ >= 1) {
    u_ = u_prev1_;
  } else {
    u_.setZero();
  }

  u_predicted_ = u_;
  // Whether this frame's prediction carries a velocity (the frame after the first, a lost frame
  // or reset_motion() predicts without one, and its miss is the whole motion, not a prediction
  // error: the frame after it trusts its first velocity, with the narrow search's retry as the
  // safety net).
  const bool with_velocity =
      frames_ >= 2 && options_.predict && !previous_lost_ && std::isfinite(last_miss_px_);

  bool converged = false, failed = false;
  double last_move = std::numeric_limits<double>::infinity();
  // The first frame is where the initial polyline was drawn: no motion to catch up with. Later,
  // the first repetition searches wide only when the prediction may be off (see predictable_px).
  bool wide_first = frames_ > 0 && (frames_ < 2 || !options_.predict || previous_lost_ ||
                                    options_.observation != ObservationMode::kEdge ||
                                    !(last_miss_px_ <= options_.predictable_px));
  bool coarse_candidates = false;
  // The last polishing steps are skipped (see below) unless the forces are verified: per-node
  // forces are derivatives of the shape, and a forward solve of a slender beam needs the polished
  // fit (measured: thin cantilever, 2 of 40 frames fail to verify without it).
  const bool polish_optional = !options_.verify_forces;
  for (int rep = 0; rep < options_.max_repetitions && !failed; ++rep) {
    const bool wide = rep == 0 && wide_first;
    // After a lost frame the object may have moved for several frames: search twice as wide.
    const int wide_range = previous_lost_ ? std::min(2 * options_.first_search_range_px, 200)
                                          : options_.first_search_range_px;
    // Search lines keep their position between repetitions, so their candidates stay valid while
    // the model moves little: search again only after a move larger than research_px.
    // The wide search's candidates come from one pixel row: always search again after it.
    if (rep == 0 || coarse_candidates ||
        max_node_distance(u_, u_searched_) > options_.research_px) {
      coarse_candidates = wide && options_.observation == ObservationMode::kEdge;
      const auto s0 = std::chrono::steady_clock::now();
      search(frame, wide ? wide_range : options_.search_range_px);
      summary.search_seconds +=
          std::chrono::duration<double>(std::chrono::steady_clock::now() - s0).count();
      u_searched_ = u_;
      ++summary.searches;
    }
    strongest_candidate_ = wide;
    u_start_ = u_;
    internal_force_at_start();
    ++summary.repetitions;
    double step = 0.0;
    for (int it = 0; it < options_.max_newton_iterations; ++it) {
      if (!newton_step()) {
        failed = true;
        break;
      }
      ++summary.iterations;
      step = 0.0;
      for (int i = 0; i < model_.num_nodes(); ++i)
        step = std::max(step, du_.segment<2>(3 * i).norm());
      // The repetition has converged once a step is a fraction of the frame's tolerance (steps
      // shrink ~10x per iteration; a tighter bound costs an iteration and moves nothing).
      if (step < 0.25 * options_.convergence_px) break;
      // After the first repetition, a first step below the frame's tolerance ends the frame: the
      // repetition cannot move the model by more than the tolerance (the steps that would follow
      // are a tenth of this one), so the convergence test below passes either way.
      if (rep > 0 && it == 0 && step < options_.convergence_px && polish_optional) break;
    }
    if (rep == 0 && frames_ > 0 && !wide && !failed && object_fraction_at_last_step() < 0.5) {
      // The narrow search around the prediction did not find the object: the motion outran the
      // prediction. Start the frame again with the wide search.
      u_ = u_predicted_;
      wide_first = true;
      rep = -1;
      continue;
    }
    // Converged when a repetition no longer moves the model, or when the moves have stalled at a
    // small noise floor (the search re-samples noisy profiles at slightly different positions, so
    // consecutive repetitions can alternate by a few hundredths of a pixel).
    const double move = rms_node_distance(u_, u_start_);
    if (!failed && (move < options_.convergence_px ||
                    (move < 4.0 * options_.convergence_px && move > 0.9 * last_move))) {
      converged = true;
      break;
    }
    // The next repetition's move, predicted instead of taken: when this one ended with a step
    // below the tolerance and the next would re-use the candidates, its gradient differs from
    // this one's last only by the new bending reference, Δp = p_ref(u) − p_ref(u_start), so its
    // first step is K⁻¹Δp on the last factorisation (one block-tridiagonal solve instead of a
    // Newton iteration), and the steps after it are a quarter of the last one at most. Applied,
    // and the frame ends, when that is below the tolerance.
    if (!failed && polish_optional && options_.model == TrackerModel::kBeam &&
        !options_.dense_solve && step < options_.convergence_px && !coarse_candidates &&
        max_node_distance(u_, u_searched_) <= options_.research_px) {
      bending_reference_force(p_next_);
      du_ = p_next_ - p_ref_;
      const auto& fixed = model_.fixed_mask();
      for (Eigen::Index k = 0; k < du_.size(); ++k) {
        if (fixed[k]) du_[k] = 0.0;
      }
      ldlt_.solve_in_place(du_);
      double predicted = 0.0;
      for (int i = 0; i < model_.num_nodes(); ++i)
        predicted = std::max(predicted, du_.segment<2>(3 * i).norm());
      if (du_.allFinite() && predicted + 0.25 * step < options_.convergence_px) {
        u_ += du_;
        converged = true;
        ++summary.predicted;
        break;
      }
    }
    last_move = move;
  }

  // Final residuals: RMS of the inliers and the fraction of search lines that found one. A
  // converged frame keeps those of its last Newton step (nearest-candidate association, within
  // convergence_px of the final state: a fraction of the residual bounds below); otherwise they
  // are evaluated again at the final state.
  const bool reuse = converged && !strongest_candidate_;
  strongest_candidate_ = false;
  const double cutoff = failed ? 0.0 : reuse ? cutoff_ : residuals();
  int inliers = 0, inside = 0;
  double sum_sq = 0.0;
  for (std::size_t l = 0; l < lines_.size(); ++l) {
    const Eigen::Vector2d& c = lines_[l].centre;  // inside where ImageView::sample would read
    if (c.x() >= 0.0 && c.y() >= 0.0 && c.x() <= frame.width - 1.0 && c.y() <= frame.height - 1.0)
      ++inside;
    if (std::abs(residual_[l]) < cutoff) {
      ++inliers;
      sum_sq += double(residual_[l]) * residual_[l];
    }
  }
  summary.search_lines = inside;
  summary.inlier_fraction = lines_.empty() ? 0.0 : double(inliers) / double(lines_.size());
  summary.rms_px = inliers > 0 ? std::sqrt(sum_sq / inliers) : 0.0;

  // An inlier only counts as the object if its response is comparable to the object's typical
  // one (a running median over good frames): with the object gone, the search still finds noise
  // and clutter, which a robust fit happily explains.
  // In edge mode both boundaries of a sample must be such inliers: a thin clutter line has two
  // edges a few pixels apart, never one at each side of the object's width.
  int strong = 0, strong_samples = 0;
  const float threshold = static_cast<float>(options_.min_relative_strength * typical_strength_);
  // The residual bound is absolute: with the object gone the robust scale itself grows (24 px
  // measured), and everything would pass a scaled test.
  const double near = std::min(cutoff, options_.object_residual_px);
  auto object_like = [&](std::size_t l) {
    return std::abs(residual_[l]) < near && strength_[l] >= threshold;
  };
  for (std::size_t l = 0; l < lines_.size(); ++l) {
    if (!(std::abs(residual_[l]) < cutoff)) continue;
    sorted_[strong_samples++] = strength_[l];
    if (!object_like(l)) continue;
    if (sides_ == 2 && lines_[l].end == 0) {
      // Lines come in (−side, +side) pairs of the same sample point.
      const std::size_t partner = lines_[l].side < 0 ? l + 1 : l - 1;
      if (!object_like(partner)) continue;
    }
    ++strong;
  }
  summary.object_fraction = lines_.empty() ? 0.0 : double(strong) / double(lines_.size());

  if (failed || !u_.allFinite() || summary.inlier_fraction < options_.min_inlier_fraction ||
      summary.object_fraction < options_.min_inlier_fraction) {
    summary.status = FrameStatus::kLost;
    last_accepted_ = false;
    verify_have_previous_ = false;
    // Keep the last good state and forget the velocity: the next frame searches from there.
    if (frames_ >= 1) {
      u_ = u_prev1_;
    } else {
      u_.setZero();
    }
    u_prev2_ = u_prev1_;
    previous_lost_ = true;
    return finish();
  }
  summary.status = converged ? FrameStatus::kOk : FrameStatus::kNotConverged;
  previous_lost_ = false;
  last_accepted_ = true;
  if (strong_samples > 0) {
    const double median = detail::kth_smallest(sorted_.data(), strong_samples, strong_samples / 2);
    typical_strength_ = frames_ == 0 ? median : 0.8 * typical_strength_ + 0.2 * median;
  }
  last_miss_px_ = with_velocity ? max_node_distance(u_, u_predicted_) : 0.0;
  u_prev2_ = frames_ >= 1 ? u_prev1_ : u_;
  u_prev1_ = u_;
  ++frames_;

  if (options_.model == TrackerModel::kBeam) {
    Eigen::Ref<Eigen::VectorXd> f(forces_);
    model_.evaluate(u_, nullptr, &f, nullptr);  // f = p(u_T): the load that holds this shape
    if (options_.verify_forces) verify(summary);
    if (!load_nodes_.empty()) fit_loads(summary);
  }
  return finish();
}

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
