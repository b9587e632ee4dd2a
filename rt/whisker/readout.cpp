#include "rt/whisker/readout.hpp"

#include <algorithm>
#include <cmath>

#include "common/detail/field_error.hpp"
#include "rt/centreline.hpp"

namespace sinew::rt {

namespace {

std::string field_error(const char* field, double value, const char* constraint) {
  return common::detail::field_error("whisker read-out: ", field, value, constraint);
}

double wrap_degrees(double a) {
  a = std::fmod(a + 180.0, 360.0);
  if (a <= 0.0) a += 360.0;
  return a - 180.0;
}

}  // namespace

namespace {

struct NamedWhisker {
  const char* name;
  double young_modulus_gpa, base_radius_um, tip_radius_um, length_mm;
};

// The sources of each value: readout.hpp, whisker_preset().
constexpr NamedWhisker kPresets[] = {
    {"rat-c2", 3.34, 69.5, 1.6, 33.6},
    {"mouse-c2", 3.34, 33.5, 1.5, 13.2},  // the modulus is the rat's: none measured in mice
};

}  // namespace

std::optional<WhiskerPhysics> whisker_preset(std::string_view name) {
  for (const NamedWhisker& w : kPresets) {
    if (name != w.name) continue;
    WhiskerPhysics p;
    p.young_modulus_gpa = w.young_modulus_gpa;
    p.base_radius_um = w.base_radius_um;
    p.tip_radius_um = w.tip_radius_um;
    p.length_mm = w.length_mm;
    return p;
  }
  return std::nullopt;
}

const std::vector<std::string>& whisker_preset_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (const NamedWhisker& w : kPresets) n.emplace_back(w.name);
    return n;
  }();
  return names;
}

std::optional<std::string> WhiskerPhysics::validate() const {
  if (!(mm_per_px >= 0.0)) return field_error("mm_per_px", mm_per_px, "must be >= 0");
  if (!(young_modulus_gpa > 0.0))
    return field_error("young_modulus_gpa", young_modulus_gpa, "must be > 0");
  if (!(poisson_ratio > -1.0 && poisson_ratio < 0.5))
    return field_error("poisson_ratio", poisson_ratio, "must be in (-1, 0.5)");
  if (!(length_mm >= 0.0)) return field_error("length_mm", length_mm, "must be >= 0");
  if (si()) {
    if (!(base_radius_um > 0.0)) {
      return field_error("base_radius_um", base_radius_um,
                         "must be > 0 with an image scale (the whisker's radius at the follicle)");
    }
    if (!(tip_radius_um >= 0.0 && tip_radius_um <= base_radius_um)) {
      return field_error("tip_radius_um", tip_radius_um, "must be in [0, base_radius_um]");
    }
  }
  return std::nullopt;
}

common::BeamSection WhiskerPhysics::section_at(double s_mm, double whisker_length_mm) const {
  const double length = length_mm > 0.0 ? length_mm : whisker_length_mm;
  const double t = length > 0.0 ? std::clamp(s_mm / length, 0.0, 1.0) : 0.0;
  const double r = 1e-6 * (base_radius_um + (tip_radius_um - base_radius_um) * t);
  const double E = young_modulus_gpa * 1e9;
  const double G = E / (2.0 * (1.0 + poisson_ratio));
  const double area = M_PI * r * r;
  return {E * area, 0.9 * G * area, E * M_PI * r * r * r * r / 4.0};
}

std::optional<std::string> WhiskerReadoutOptions::validate() const {
  if (auto err = physics.validate()) return err;
  if (!std::isfinite(axis_angle_deg))
    return field_error("axis_angle_deg", axis_angle_deg, "must be finite");
  if (!(curvature_from_px >= 0.0))
    return field_error("curvature_from_px", curvature_from_px, "must be >= 0");
  if (!(curvature_to_px > curvature_from_px))
    return field_error("curvature_to_px", curvature_to_px, "must be > curvature_from_px");
  if (moment_elements < 1) return field_error("moment_elements", moment_elements, "must be >= 1");
  return std::nullopt;
}

WhiskerReadoutModel::WhiskerReadoutModel(const common::BeamModel& model,
                                         WhiskerReadoutOptions options)
    : options_(options) {
  if (auto err = options_.validate()) {
    error_ = *err;
    return;
  }
  if (!model.valid() || model.num_elements() < 1) {
    error_ = "whisker read-out: the beam has no element";
    return;
  }
  rest_ = model.rest_positions();
  tangents_ = polyline_node_tangents(rest_);
  const int n = model.num_nodes();
  arc_.resize(n);
  arc_[0] = 0.0;
  for (int e = 0; e < model.num_elements(); ++e) arc_[e + 1] = arc_[e] + model.element(e).length;
  const double length_px = arc_[n - 1];
  from_px_ = std::min(options_.curvature_from_px, length_px);
  to_px_ = std::min(options_.curvature_to_px, length_px);
  if (!(to_px_ > from_px_)) {
    error_ = "whisker read-out: the curvature window starts at " +
             std::to_string(options_.curvature_from_px) + " px, beyond the whisker's " +
             std::to_string(length_px) + " px";
    return;
  }

  const WhiskerPhysics& ph = options_.physics;
  if (ph.si()) {
    // Lengths in metres, the first element's section at its midpoint's radius.
    length_unit_ = ph.mm_per_px * 1e-3;
    curvature_unit_ = 1.0 / ph.mm_per_px;  // 1/px → 1/mm
    section_ =
        ph.section_at(0.5 * model.element(0).length * ph.mm_per_px, length_px * ph.mm_per_px);
    reference_ = common::make_beam_element_reference(rest_.col(0) * length_unit_,
                                                     rest_.col(1) * length_unit_);
  } else {
    section_ = model.description().sections[0];
    reference_ = model.element(0);
  }
  // The elements M0 is read from.
  const int k = std::min(options_.moment_elements, model.num_elements());
  bending_.resize(k);
  midpoint_.resize(k);
  length_px_.resize(k);
  rest_moment_ = Eigen::VectorXd::Zero(k);
  for (int e = 0; e < k; ++e) {
    length_px_[e] = model.element(e).length;
    midpoint_[e] = (arc_[e] + 0.5 * length_px_[e]) * length_unit_;
    if (ph.si()) {
      bending_[e] = ph.section_at(midpoint_[e] * 1e3, length_px * ph.mm_per_px).EI;
    } else {
      bending_[e] = model.description().sections[e].EI;
    }
  }
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(model.num_dofs());
  const WhiskerReadout rest = evaluate(zero);
  rest_curvature_ = rest.curvature;
}

namespace {

// Unit tangent of the Hermite centreline at reference arc length s (pixels) at state u.
Eigen::Vector2d tangent_at(const Eigen::Matrix2Xd& rest, const Eigen::Matrix2Xd& tangents,
                           const Eigen::VectorXd& arc, const Eigen::Ref<const Eigen::VectorXd>& u,
                           double s) {
  const int elements = static_cast<int>(arc.size()) - 1;
  int e = 0;
  while (e + 1 < elements && arc[e + 1] < s) ++e;
  const double length = arc[e + 1] - arc[e];
  const double xi = std::clamp((s - arc[e]) / length, 0.0, 1.0);
  const common::BeamElementReference ref =
      common::make_beam_element_reference(rest.col(e), rest.col(e + 1));
  const CentrelinePoint p = hermite_centreline(rest.col(e), ref, tangents.col(e),
                                               tangents.col(e + 1), u.segment<6>(3 * e), xi);
  // The normal is the tangent turned by +90°.
  return Eigen::Vector2d(p.normal.y(), -p.normal.x());
}

}  // namespace

common::Vector6d WhiskerReadoutModel::first_element_load(
    const Eigen::Ref<const Eigen::VectorXd>& u) const noexcept {
  common::Vector6d ue = u.segment<6>(0);
  for (int i : {0, 1, 3, 4}) ue[i] *= length_unit_;  // pixels → the reported length unit
  common::Vector6d p;
  common::evaluate_beam_element(reference_, section_, common::BeamPrestress{}, ue, nullptr, &p,
                                nullptr);
  return p;
}

void WhiskerReadoutModel::set_rest(const Eigen::Ref<const Eigen::VectorXd>& u) noexcept {
  rest_curvature_ = 0.0;
  rest_load_.setZero();
  rest_moment_.setZero();
  const WhiskerReadout r = evaluate(u);
  rest_curvature_ = r.curvature;
  // The first element's load at rest, in full (force and its moment at the node).
  rest_load_ = first_element_load(u);
  for (int i = 3; i < 6; ++i) rest_load_[i] = 0.0;
  for (int e = 0; e < rest_moment_.size(); ++e) {
    rest_moment_[e] = bending_[e] * (u[3 * e + 5] - u[3 * e + 2]) / length_px_[e] / length_unit_;
  }
}

WhiskerReadout WhiskerReadoutModel::evaluate(
    const Eigen::Ref<const Eigen::VectorXd>& u) const noexcept {
  WhiskerReadout r;
  // The tangent at the follicle: the node's reference tangent turned by its rotation.
  const double c = std::cos(u[2]), s = std::sin(u[2]);
  const Eigen::Vector2d T0 = tangents_.col(0);
  const Eigen::Vector2d t0(c * T0.x() - s * T0.y(), s * T0.x() + c * T0.y());
  r.base_angle_deg =
      wrap_degrees(std::atan2(t0.y(), t0.x()) * 180.0 / M_PI - options_.axis_angle_deg);

  const Eigen::Vector2d ta = tangent_at(rest_, tangents_, arc_, u, from_px_);
  const Eigen::Vector2d tb = tangent_at(rest_, tangents_, arc_, u, to_px_);
  const double turn = std::atan2(ta.x() * tb.y() - ta.y() * tb.x(), ta.dot(tb));
  r.curvature = turn / (to_px_ - from_px_) * curvature_unit_;
  r.delta_curvature = r.curvature - rest_curvature_;

  // The follicle's load on the whisker: the first element's internal force at its first node.
  common::Vector6d p = first_element_load(u);
  p -= rest_load_;
  r.force = p.head<2>();
  r.moment_first_element = p[2];
  // The follicle's moment on the whisker, −E·I·Δκ (the load p of the first node has this sign),
  // at the first elements' midpoints (κ per reported length), the least-squares line through them
  // evaluated at the follicle (s = 0).
  const int k = static_cast<int>(bending_.size());
  double sw = 0.0, ss = 0.0, sm = 0.0, ssm = 0.0;
  for (int e = 0; e < k; ++e) {
    const double kappa = (u[3 * e + 5] - u[3 * e + 2]) / length_px_[e] / length_unit_;
    const double m = rest_moment_[e] - bending_[e] * kappa;
    sw += 1.0;
    ss += midpoint_[e];
    sm += m;
    ssm += midpoint_[e] * m;
  }
  double s2 = 0.0;
  for (int e = 0; e < k; ++e) s2 += midpoint_[e] * midpoint_[e];
  const double det = sw * s2 - ss * ss;
  r.moment = k >= 2 && det > 0.0 ? (s2 * sm - ss * ssm) / det : sm / sw;
  r.force_axial = r.force.dot(t0);
  r.force_lateral = r.force.dot(Eigen::Vector2d(-t0.y(), t0.x()));
  return r;
}

}  // namespace sinew::rt
