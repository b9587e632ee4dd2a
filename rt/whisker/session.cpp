#include "rt/whisker/session.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <utility>

#include "common/timing.hpp"
#include "rt/whisker/taper_length.hpp"

namespace sinew::rt {

using common::seconds_since;

const char* to_string(Redetect redetect) {
  switch (redetect) {
    case Redetect::kEvery:
      return "every";
    case Redetect::kLost:
      return "lost";
    case Redetect::kNever:
      return "never";
  }
  return "?";
}

std::optional<Redetect> redetect_from_string(const std::string& name) {
  for (Redetect r : {Redetect::kEvery, Redetect::kLost, Redetect::kNever}) {
    if (name == to_string(r)) return r;
  }
  return std::nullopt;
}

std::optional<std::string> WhiskerSessionOptions::validate() const {
  if (auto err = detection.validate()) return "detection: " + *err;
  if (auto err = tracker.validate()) return *err;
  if (auto err = readout.validate()) return "read-out: " + *err;
  if (auto err = contact_fit.validate()) return "contact fit: " + *err;
  if (rest_frame < 0) {
    return "options.rest_frame = " + std::to_string(rest_frame) + ": must be >= 0";
  }
  if (rest_frames < 1) {
    return "options.rest_frames = " + std::to_string(rest_frames) + ": must be >= 1";
  }
  return std::nullopt;
}

WhiskerSession::WhiskerSession(WhiskerSessionOptions options) : options_(std::move(options)) {}

std::string WhiskerSession::process(const ImageView& frame) {
  if (!tracker_) {
    if (auto err = options_.validate()) return *err;
    const auto t0 = std::chrono::steady_clock::now();
    first_ = detect_whiskers(frame, options_.detection, detection_workspace_);
    first_seconds_ = seconds_since(t0);
    if (!first_.error.empty()) return first_.error;
    std::vector<std::vector<Eigen::Vector2d>> traces;
    for (const auto& w : first_.whiskers) traces.push_back(w.points);
    WhiskerTrackerOptions track_options = options_.tracker;
    track_options.tracker.ridge_min_background =
        dark_threshold(options_.detection.dark_fraction, first_.backlight, first_.dark_level);
    // The follicle's search wants the face's edge to fall by at least this per pixel (6 grey
    // levels, set on the shared video): on a face that stands out less, the edge falls less
    // (docs/whisker_benchmark.md).
    track_options.tracker.dark_region_min_step *=
        contrast_scale(first_.backlight, first_.dark_level);
    WhiskerTracker tracker(traces, track_options);
    if (!tracker.valid()) return tracker.error();
    std::vector<WhiskerReadoutModel> readouts;
    for (int w = 0; w < tracker.num_whiskers(); ++w) {
      readouts.emplace_back(tracker.whisker(w).model(), options_.readout);
      if (!readouts.back().valid()) {
        return "whisker " + std::to_string(w) + ": " + readouts.back().error();
      }
    }
    tracker_.emplace(std::move(tracker));
    readouts_ = std::move(readouts);
    whiskers_.resize(readouts_.size());
    rest_taken_.assign(readouts_.size(), 0);
    rest_count_.assign(readouts_.size(), 0);
    rest_sum_.resize(readouts_.size());
    rest_state_.resize(readouts_.size());
    contact_target_.resize(readouts_.size());
    contact_fit_.resize(readouts_.size());
    quiet_moments_.assign(readouts_.size(),
                          Eigen::VectorXd::Zero(WhiskerSessionWhisker::kQuietFrames));
    quiet_count_.assign(readouts_.size(), 0);
  }
  tracking_seconds_ = tracker_->track(frame);
  // The first frame's fits are the whiskers at rest (Δκ and M0 are changes from them) until the
  // rest frame's.
  if (frames_ == 0) {
    physics_.assign(readouts_.size(), options_.readout.physics);
    taper_.assign(readouts_.size(), TaperLength{});
    for (int w = 0; w < tracker_->num_whiskers(); ++w) {
      const Tracker& t = tracker_->whisker(w);
      Eigen::Matrix2Xd nodes(2, t.num_nodes());
      for (int i = 0; i < t.num_nodes(); ++i) nodes.col(i) = t.node_position(i);
      WhiskerPhysics& ph = physics_[w];
      // The cone's whole length, where the user gave none: from the whisker's darkness along it
      // (rt/whisker/taper_length.hpp), else the tracked length as before.
      if (ph.si() && !(ph.length_mm > 0.0) && ph.base_radius_um > 0.0) {
        taper_[w] = taper_length(frame, nodes, ph.tip_radius_um / ph.base_radius_um);
        if (taper_[w].measured) {
          ph.length_mm = taper_[w].length_px * ph.mm_per_px;
          WhiskerReadoutOptions ro = options_.readout;
          ro.physics = ph;
          WhiskerReadoutModel model(t.model(), ro);
          if (model.valid()) {
            readouts_[w] = std::move(model);
          } else {
            ph.length_mm = options_.readout.physics.length_mm;
          }
        }
      } else {
        taper_[w].tracked_px = t.model().total_length();
        taper_[w].length_px =
            ph.length_mm > 0.0 && ph.si() ? ph.length_mm / ph.mm_per_px : taper_[w].tracked_px;
      }
      readouts_[w].set_rest(t.state());
    }
  }
  ++frames_;
  // Detection again, outside the real-time path: the whiskers are matched to it in their order
  // along the face, and lost or misplaced ones restart on theirs.
  association_ = WhiskerAssociation{};
  redetected_ = options_.redetect == Redetect::kEvery ||
                (options_.redetect == Redetect::kLost && tracker_->any_lost());
  redetect_seconds_ = 0.0;
  bool have_objects = false;
  if (redetected_) {
    const auto t0 = std::chrono::steady_clock::now();
    WhiskerDetection again = detect_whiskers(frame, options_.detection, detection_workspace_);
    std::vector<std::vector<Eigen::Vector2d>> traces;
    std::vector<double> contrasts;
    for (const auto& w : again.whiskers) {
      traces.push_back(w.points);
      contrasts.push_back(w.contrast_percent);
    }
    if (again.error.empty()) association_ = tracker_->associate(frame, traces, contrasts);
    object_distance_ = std::move(again.object_distance);
    have_objects = again.error.empty();
    redetect_seconds_ = seconds_since(t0);
  }
  const auto readout_start = std::chrono::steady_clock::now();
  for (int w = 0; w < tracker_->num_whiskers(); ++w) {
    WhiskerSessionWhisker& out = whiskers_[w];
    out = WhiskerSessionWhisker{};
    if (tracker_->result(w).status != FrameStatus::kOk) continue;
    const Tracker& t = tracker_->whisker(w);
    out.readout = readouts_[w].evaluate(t.state());
    if (have_objects) {
      out.contact = object_distance_.empty()
                        ? WhiskerContact{}
                        : find_contact(t, object_distance_.data(), frame.width, frame.height);
      if (out.contact->touching && contact_fit_[w]) {
        out.contact_load = fit_contact(w, *out.contact);
        // An object only pushes: a load that would pull the whisker onto it says the whisker is
        // near it, not pressed (it lingers within the touch distance as it leaves slowly).
        const Eigen::Vector2d away = away_from_objects(object_distance_.data(), frame.width,
                                                       frame.height, out.contact->point);
        if (out.contact_load->equilibrium && out.contact_load->force.dot(away) < 0.0) {
          out.contact->touching = false;
          out.contact_load.reset();
        }
      }
      if (out.contact_load) pammer(w, *out.readout, *out.contact, &*out.contact_load);
    }
    moment_noise(w);
  }
  readout_seconds_ = seconds_since(readout_start);
  // The rest shape: from the rest frame on, frames tracked ok and touching nothing.
  if (frames_ - 1 >= options_.rest_frame) {
    for (int w = 0; w < tracker_->num_whiskers(); ++w) {
      const WhiskerSessionWhisker& out = whiskers_[w];
      if (rest_taken_[w] || tracker_->result(w).status != FrameStatus::kOk) continue;
      if (out.contact && out.contact->touching) continue;
      accumulate_rest(w);
    }
  }
  return {};
}

common::BeamDescription contact_fit_beam(const common::BeamModel& tracked,
                                         const Eigen::VectorXd& rest,
                                         const WhiskerPhysics& physics) {
  common::BeamDescription d = tracked.description();
  d.rest_positions = tracked.current_positions(rest);
  d.fixed.clear();
  d.clamp(0);
  if (physics.si()) {
    const double m_per_px = physics.mm_per_px * 1e-3;
    const double length_mm = tracked.total_length() * physics.mm_per_px;
    double s_px = 0.0;
    for (int e = 0; e < tracked.num_elements(); ++e) {
      const double le = tracked.element(e).length;
      d.sections[e] = physics.section_at((s_px + 0.5 * le) * physics.mm_per_px, length_mm);
      d.sections[e].EI /= m_per_px * m_per_px;
      s_px += le;
    }
  }
  return d;
}

common::BeamDescription contact_fit_beam(const Tracker& whisker, const Eigen::VectorXd& rest,
                                         const WhiskerPhysics& physics) {
  return contact_fit_beam(whisker.model(), rest, physics);
}

void WhiskerSession::accumulate_rest(int w) {
  const Tracker& t = tracker_->whisker(w);
  const Eigen::VectorXd& u = t.state();
  const Eigen::Matrix2Xd& X = t.model().rest_positions();
  const int n = t.num_nodes();
  if (rest_count_[w] == 0) {
    rest_sum_[w] = u;
  } else {
    // Turned about its follicle onto the first frame's pose (least squares over the nodes).
    const Eigen::VectorXd& first = rest_state_[w];
    const Eigen::Vector2d x0 = X.col(0) + u.segment<2>(0);
    const Eigen::Vector2d r0 = X.col(0) + first.segment<2>(0);
    double num = 0.0, den = 0.0;
    for (int i = 1; i < n; ++i) {
      const Eigen::Vector2d a = X.col(i) + u.segment<2>(3 * i) - x0;
      const Eigen::Vector2d b = X.col(i) + first.segment<2>(3 * i) - r0;
      num += a.x() * b.y() - a.y() * b.x();
      den += a.dot(b);
    }
    const double phi = std::atan2(num, den);
    const Eigen::Rotation2Dd R(phi);
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector2d x = r0 + R * (X.col(i) + u.segment<2>(3 * i) - x0);
      rest_sum_[w].segment<2>(3 * i) += x - X.col(i);
      rest_sum_[w][3 * i + 2] += u[3 * i + 2] + phi;
    }
  }
  if (rest_count_[w] == 0) rest_state_[w] = u;  // the pose the others are turned onto
  if (++rest_count_[w] == options_.rest_frames) {
    take_rest(w, rest_sum_[w] / static_cast<double>(options_.rest_frames));
  }
}

void WhiskerSession::moment_noise(int w) {
  WhiskerSessionWhisker& out = whiskers_[w];
  constexpr int kRing = WhiskerSessionWhisker::kQuietFrames;
  if (rest_taken_[w] && out.contact && !out.contact->touching) {
    const double m = out.readout->moment;
    quiet_moments_[w][quiet_count_[w] % kRing] = m * m;
    ++quiet_count_[w];
  }
  const int n = std::min(quiet_count_[w], kRing);
  if (n < WhiskerSessionWhisker::kQuietFramesMin) return;
  // The RMS about zero (no load, no moment): its tails are the tracking's, heavier than a
  // Gaussian's, and a robust scale (1.4826 × the median) left |M0| beyond 3 of it on 2.3–7.9 %
  // of the rendered pads' quiet frames where the RMS leaves 0.8–2.1 % (docs/tracker.md).
  out.moment_sd = std::sqrt(quiet_moments_[w].head(n).sum() / n);
}

void WhiskerSession::take_rest(int w, const Eigen::VectorXd& u) {
  const Tracker& t = tracker_->whisker(w);
  readouts_[w].set_rest(u);
  rest_state_[w] = u;
  contact_target_[w].setZero(u.size());
  rest_taken_[w] = 1;
  if (!options_.contact_load) return;
  LoadFitOptions o = options_.contact_fit;
  o.max_load_points = 1;
  contact_fit_[w].emplace(contact_fit_beam(t, u, physics_[w]), o);
  if (!contact_fit_[w]->valid()) contact_fit_[w].reset();
}

WhiskerSessionWhisker::ContactLoad WhiskerSession::fit_contact(int w, const WhiskerContact& c) {
  const Tracker& t = tracker_->whisker(w);
  LoadFit& fit = *contact_fit_[w];
  // Against the rest shape: displacements and rotations since the rest frame.
  contact_target_[w] = t.state() - rest_state_[w];
  // The contact by arc length along the tracked whisker: between the fit's fine nodes `point`
  // and the next, `fraction` of the way (LoadFit's consistent nodal loads), at least at node 1.
  const int fine = fit.model().num_nodes();
  const double length = tracker_->result(w).length_px;
  const double at = std::clamp(c.arc_length_px / length * (fine - 1), 1.0, fine - 1.0);
  const int point = std::min(static_cast<int>(at), fine - 1);
  const double fraction = at - point;
  // A frictionless contact pushes along the whisker's normal there: the tracked element's.
  const int elements = t.num_nodes() - 1;
  const int e = std::clamp(point * elements / (fine - 1), 0, elements - 1);
  const Eigen::Vector2d chord = (t.node_position(e + 1) - t.node_position(e)).normalized();
  const double normal[2] = {-chord.y(), chord.x()};
  const LoadFitSummary s = fit.fit(contact_target_[w], &point, 1, normal, &fraction);
  WhiskerSessionWhisker::ContactLoad load;
  load.converged = s.converged;
  load.rms_px = s.rms_px;
  // A fit that found no equilibrium has no load to report (e.g. the tracked whisker ran onto the
  // pole, and no force at the contact bends the beam that far): not the reset fit's zero.
  load.equilibrium = s.equilibrium;
  if (!s.equilibrium) return load;
  load.force = fit.loads()[0] * Eigen::Vector2d(normal[0], normal[1]);
  const Eigen::Matrix2Xd& X = fit.model().rest_positions();
  load.point = X.col(point) + fit.state().segment<2>(3 * point);
  if (point + 1 < fine) {
    load.point +=
        fraction * (X.col(point + 1) + fit.state().segment<2>(3 * point + 3) - load.point);
  }
  const Eigen::Vector2d arm = load.point - (X.col(0) + fit.state().segment<2>(0));
  // With a scale the force is in newtons and the arm in pixels: the moment in N·m.
  const WhiskerPhysics& ph = options_.readout.physics;
  const double arm_unit = ph.si() ? ph.mm_per_px * 1e-3 : 1.0;
  load.moment = arm_unit * (arm.x() * load.force.y() - arm.y() * load.force.x());
  // The base tangent of the fitted equilibrium: the rest beam's first chord turned by the
  // follicle's fitted rotation.
  const Eigen::Vector2d base =
      Eigen::Rotation2Dd(fit.state()[2]) * (X.col(1) - X.col(0)).normalized();
  load.follicle_axial = -load.force.dot(base);
  load.follicle_lateral = load.force.y() * base.x() - load.force.x() * base.y();
  // Standard deviations: each value is linear in the force's magnitude q, the follicle's
  // components also depend on the fitted follicle angle (the base tangent turns with it), so
  // σ² = gᵀ C g over (q, angle) with C the fit's covariance (the angle second when fitted).
  load.noise_px = s.noise_px;
  const Eigen::Vector2d n(normal[0], normal[1]), turned(-base.y(), base.x());
  const double q = fit.loads()[0];
  const auto C = fit.covariance();
  const bool angle = fit.options().fit_base_rotation;
  const auto sd = [&](double dq, double dangle) {
    double v = dq * dq * C(0, 0);
    if (angle) v += 2.0 * dq * dangle * C(0, 1) + dangle * dangle * C(1, 1);
    return std::sqrt(std::max(v, 0.0));
  };
  load.force_sd = sd(1.0, 0.0);
  load.moment_sd = sd(arm_unit * (arm.x() * n.y() - arm.y() * n.x()), 0.0);
  load.follicle_axial_sd = sd(-n.dot(base), -q * n.dot(turned));
  load.follicle_lateral_sd =
      sd(n.y() * base.x() - n.x() * base.y(), q * (n.y() * turned.x() - n.x() * turned.y()));
  return load;
}

namespace {

// A point at arc length s along the tracked whisker's node polyline, and its chord's unit tangent.
std::pair<Eigen::Vector2d, Eigen::Vector2d> along_nodes(const Tracker& t, double s) {
  double walked = 0.0;
  const int elements = t.num_nodes() - 1;
  for (int e = 0; e < elements; ++e) {
    const Eigen::Vector2d a = t.node_position(e), b = t.node_position(e + 1);
    const double length = (b - a).norm();
    if (walked + length >= s || e == elements - 1) {
      const double f = length > 0.0 ? std::clamp((s - walked) / length, 0.0, 1.0) : 0.0;
      return {a + f * (b - a),
              length > 0.0 ? Eigen::Vector2d((b - a) / length) : Eigen::Vector2d(1.0, 0.0)};
    }
    walked += length;
  }
  return {t.node_position(0), Eigen::Vector2d(1.0, 0.0)};
}

}  // namespace

void WhiskerSession::pammer(int w, const WhiskerReadout& readout, const WhiskerContact& c,
                            WhiskerSessionWhisker::ContactLoad* load) const {
  const Tracker& t = tracker_->whisker(w);
  const WhiskerReadoutOptions& ro = options_.readout;
  // Δκ per pixel and E·I per pixel² in the contact load's units: the trackers' E·I (model
  // units), or with a scale the cone's at p over (metres per pixel)² (force in newtons).
  const double dk =
      ro.physics.si() ? readout.delta_curvature * ro.physics.mm_per_px : readout.delta_curvature;
  const double window_centre_px = 0.5 * (ro.curvature_from_px + ro.curvature_to_px);
  const double h = WhiskerTrackerOptions::kModelSectionHeightPx;
  double EI = WhiskerTrackerOptions::kModelYoungModulus * h * h * h / 12.0;
  if (ro.physics.si()) {
    const double m_per_px = ro.physics.mm_per_px * 1e-3;
    EI = physics_[w]
             .section_at(window_centre_px * ro.physics.mm_per_px,
                         t.model().total_length() * ro.physics.mm_per_px)
             .EI /
         (m_per_px * m_per_px);
  }
  const auto [xp, tp] = along_nodes(t, window_centre_px);
  const auto [xc, tc] = along_nodes(t, c.arc_length_px);
  const Eigen::Vector2d nc(-tc.y(), tc.x());
  auto cross = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return a.x() * b.y() - a.y() * b.x();
  };
  const double lever = cross(xc - xp, nc);
  if (!(std::abs(lever) > 1e-9)) return;
  load->pammer_force = EI * dk / lever;
  const double arm_unit = ro.physics.si() ? ro.physics.mm_per_px * 1e-3 : 1.0;
  load->pammer_moment = arm_unit * cross(xc - t.node_position(0), nc) * load->pammer_force;
}

}  // namespace sinew::rt
