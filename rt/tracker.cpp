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
  if (end_band_px < 0 || end_band_px > 10) {
    return field_error("end_band_px", end_band_px, "must be in [0, 10]");
  }
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
  if (!(start_mean_surround_px >= 0.0)) {
    return field_error("start_mean_surround_px", start_mean_surround_px, "must be >= 0");
  }
  if (!(start_clearance_px >= 0.0)) {
    return field_error("start_clearance_px", start_clearance_px, "must be >= 0");
  }
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
  // Arc length from the first node within which no line along a normal is placed.
  const double clearance =
      start_free && options_.start_end == StartEnd::kDarkRegion ? options_.start_clearance_px : 0.0;
  double s0 = 0.0;  // arc length of the element's first node
  for (int e = 0; e < elements; ++e) {
    for (int s = 0; s < options_.samples_per_element; ++s) {
      const float xi = static_cast<float>((s + 0.5) / options_.samples_per_element);
      if (s0 + xi * model_.element(e).length < clearance) continue;
      sample_points_.push_back({e, xi, hermite_basis(xi)});
      for (int side = 0; side < sides_; ++side) {
        SearchLine& line = lines_[l++];
        line.element = e;
        line.xi = xi;
        line.side = sides_ == 1 ? 0.0f : (side == 0 ? -1.0f : 1.0f);
        line.point = static_cast<int>(sample_points_.size()) - 1;
        line.mean_surround = options_.observation == ObservationMode::kDarkRidge &&
                             options_.start_end == StartEnd::kDarkRegion &&
                             s0 + xi * model_.element(e).length < options_.start_mean_surround_px;
      }
    }
    const double L0 = model_.element(e).length;
    // 12·EI/ℓ³·(L₀/ℓ) per element: 12·EI/L₀³ when ℓ = L₀, otherwise 12·EI/ℓ⁴ per unit length.
    const double ell = std::max(L0, min_image_length);
    stiffness += 12.0 * model_.description().sections[e].EI / (ell * ell * ell) * (L0 / ell);
    mean_length += L0;
    s0 += L0;
  }
  if (start_free) {
    sample_points_.push_back({0, 0.0, hermite_basis(0.0)});
    lines_[l].element = 0;
    lines_[l].xi = 0.0f;
    lines_[l].point = static_cast<int>(sample_points_.size()) - 1;
    lines_[l++].end = -1;
  }
  if (end_free) {
    sample_points_.push_back({elements - 1, 1.0, hermite_basis(1.0)});
    lines_[l].element = elements - 1;
    lines_[l].xi = 1.0f;
    lines_[l].point = static_cast<int>(sample_points_.size()) - 1;
    lines_[l++].end = 1;
  }
  lines_.resize(l);  // fewer when start_clearance_px left some out
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
        &verify_previous_forces_, &verify_backup_, &u_searched_, &p_next_, &u_points_}) {
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

void Tracker::restart_at(const Eigen::Ref<const Eigen::Matrix2Xd>& nodes, bool narrow) noexcept {
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
  narrow_next_ = narrow;
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
  narrow_next_ = false;
}

FrameSummary Tracker::track(const ImageView& frame) noexcept {
  const auto t0 = std::chrono::steady_clock::now();
  FrameSummary summary;
  auto finish = [&]() {
    summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return summary;
  };
  if (!valid() || !frame.valid()) return finish();

  const bool with_velocity = predict(frame);
  bool failed = false;
  const bool converged = repetitions(frame, summary, &failed);
  narrow_next_ = false;
  const int strong_samples = measure_fit(frame, summary, converged, failed);
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

bool Tracker::predict(const ImageView& frame) noexcept {
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
  return frames_ >= 2 && options_.predict && !previous_lost_ && std::isfinite(last_miss_px_);
}

bool Tracker::repetitions(const ImageView& frame, FrameSummary& summary,
                          bool* failed_out) noexcept {
  bool converged = false, failed = false;
  double last_move = std::numeric_limits<double>::infinity();
  // The first frame is where the initial polyline was drawn: no motion to catch up with. Later,
  // the first repetition searches wide only when the prediction may be off (see predictable_px).
  bool wide_first = !narrow_next_ && frames_ > 0 &&
                    (frames_ < 2 || !options_.predict || previous_lost_ ||
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
      step = max_node_translation(du_);
      // The repetition has converged once a step is a fraction of the frame's tolerance (steps
      // shrink ~10x per iteration; a tighter bound costs an iteration and moves nothing).
      if (step < 0.25 * options_.convergence_px) break;
      // After the first repetition, a first step below the frame's tolerance ends the frame: the
      // repetition cannot move the model by more than the tolerance (the steps that would follow
      // are a tenth of this one), so the convergence test below passes either way.
      if (rep > 0 && it == 0 && step < options_.convergence_px && polish_optional) break;
    }
    if (rep == 0 && frames_ > 0 && !wide && !failed && !narrow_next_ &&
        object_fraction_at_last_step() < 0.5) {
      // The narrow search around the prediction did not find the object: the motion outran the
      // prediction. Start the frame again with the wide search (not after restart_at(narrow):
      // the object is where it was placed, or not found).
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
    // The next repetition's move, predicted instead of taken (see take_predicted_repetition).
    if (!failed && polish_optional && take_predicted_repetition(step, coarse_candidates)) {
      converged = true;
      ++summary.predicted;
      break;
    }
    last_move = move;
  }
  *failed_out = failed;
  return converged;
}

bool Tracker::take_predicted_repetition(double step, bool coarse_candidates) noexcept {
  // The next repetition's move, predicted instead of taken: when this one ended with a step
  // below the tolerance and the next would re-use the candidates, its gradient differs from
  // this one's last only by the new bending reference, Δp = p_ref(u) − p_ref(u_start), so its
  // first step is K⁻¹Δp on the last factorisation (one block-tridiagonal solve instead of a
  // Newton iteration), and the steps after it are a quarter of the last one at most. Applied,
  // and the frame ends, when that is below the tolerance.
  if (!(options_.model == TrackerModel::kBeam && !options_.dense_solve &&
        step < options_.convergence_px && !coarse_candidates &&
        max_node_distance(u_, u_searched_) <= options_.research_px)) {
    return false;
  }
  bending_reference_force(p_next_);
  du_ = p_next_ - p_ref_;
  const auto& fixed = model_.fixed_mask();
  for (Eigen::Index k = 0; k < du_.size(); ++k) {
    if (fixed[k]) du_[k] = 0.0;
  }
  ldlt_.solve_in_place(du_);
  const double predicted = max_node_translation(du_);
  if (du_.allFinite() && predicted + 0.25 * step < options_.convergence_px) {
    u_ += du_;
    return true;
  }
  return false;
}

int Tracker::measure_fit(const ImageView& frame, FrameSummary& summary, bool converged,
                         bool failed) noexcept {
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
  return strong_samples;
}

}  // namespace sinew::rt
