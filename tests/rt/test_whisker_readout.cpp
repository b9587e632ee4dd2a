// rt::WhiskerReadoutModel: the follicle's reaction against the equilibrium of a large-deflection
// static solution, the same SI figures at two image scales, curvature and Δκ of exact arcs.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <iostream>
#include <vector>

#include "common/beam/beam_model.hpp"
#include "common/beam/static_solver.hpp"
#include "rt/centreline.hpp"
#include "rt/load_fit.hpp"
#include "rt/whisker/contact.hpp"
#include "rt/whisker/readout.hpp"
#include "rt/whisker/session.hpp"
#include "rt/whisker/whisker_tracker.hpp"

namespace sinew::rt {
namespace {

// Nodes of an arc of curvature kappa (1/px) from `base` leaving at angle `angle`, `elements`
// equal elements over `length` px.
Eigen::Matrix2Xd arc_nodes(const Eigen::Vector2d& base, double angle, double kappa, double length,
                           int elements) {
  Eigen::Matrix2Xd x(2, elements + 1);
  for (int i = 0; i <= elements; ++i) {
    const double s = length * i / elements;
    if (std::abs(kappa) < 1e-12) {
      x.col(i) = base + s * Eigen::Vector2d(std::cos(angle), std::sin(angle));
    } else {
      const double a = angle + kappa * s;
      x.col(i) =
          base +
          Eigen::Vector2d(std::sin(a) - std::sin(angle), std::cos(angle) - std::cos(a)) / kappa;
    }
  }
  return x;
}

common::BeamModel pixel_model(const Eigen::Matrix2Xd& rest) {
  common::BeamMaterial m;
  m.E = 1000.0;
  m.G = m.E / 2.6;
  m.A = 2.0;
  m.I = 8.0 / 12.0;
  return common::BeamModel(common::BeamDescription::uniform(rest, m));
}

WhiskerPhysics rat_like(double mm_per_px) {
  WhiskerPhysics p;
  p.mm_per_px = mm_per_px;
  p.young_modulus_gpa = 3.34;
  p.base_radius_um = 40.0;
  p.tip_radius_um = 2.0;
  return p;
}

// The physical whisker in millimetres and millinewtons (SI's N·m² bending stiffness of a hair,
// ~1e-9, would fall below the factorisation's pivot floor): the same rest shape, a tapered cone
// sampled at each element's midpoint (the read-out's first element uses the same rule), clamped at
// the follicle.
common::BeamModel physical_model(const Eigen::Matrix2Xd& rest_px, const WhiskerPhysics& ph) {
  common::BeamDescription d;
  d.rest_positions = rest_px * ph.mm_per_px;
  double length = 0.0;
  for (int e = 0; e + 1 < rest_px.cols(); ++e)
    length += (rest_px.col(e + 1) - rest_px.col(e)).norm() * ph.mm_per_px;
  double s = 0.0;
  // 1 GPa = 1e6 mN/mm².
  const double E = ph.young_modulus_gpa * 1e6, G = E / (2.0 * (1.0 + ph.poisson_ratio));
  for (int e = 0; e + 1 < rest_px.cols(); ++e) {
    const double le = (rest_px.col(e + 1) - rest_px.col(e)).norm() * ph.mm_per_px;
    const double t = (s + 0.5 * le) / length;
    const double r = 1e-3 * (ph.base_radius_um + (ph.tip_radius_um - ph.base_radius_um) * t);
    const double area = M_PI * r * r;
    d.sections.push_back({E * area, 0.9 * G * area, E * M_PI * std::pow(r, 4) / 4.0});
    s += le;
  }
  d.clamp(0);
  return common::BeamModel(d);
}

// The physical whisker's equilibrium under a point force F at node `node`, from its rest shape
// in 40 load increments (a large deflection).
common::StaticSolverSummary press(const common::BeamModel& phys, int node, const Eigen::Vector2d& F,
                                  Eigen::VectorXd& u) {
  Eigen::VectorXd loads = Eigen::VectorXd::Zero(phys.num_dofs());
  loads.segment<2>(3 * node) = F;
  common::StaticSolverOptions so;
  so.load_steps = 40;
  common::StaticBeamSolver solver(phys, so);
  u = Eigen::VectorXd::Zero(phys.num_dofs());
  return solver.solve(loads, u);
}

TEST(WhiskerReadout, FollicleReactionBalancesALargeDeflectionContactLoad) {
  // A 10 mm rat-like whisker (0.05 mm/px, 200 px, radius 40 → 2 µm) pushed sideways at 70 % of
  // its length by a pole: a large deflection (the tip turns by tens of degrees). The follicle's
  // load must balance the contact force and its moment about the deformed follicle exactly.
  const Eigen::Matrix2Xd rest = arc_nodes({50.0, 100.0}, 0.3, 1.0 / 600.0, 200.0, 16);
  const WhiskerPhysics ph = rat_like(0.05);
  const common::BeamModel phys = physical_model(rest, ph);
  ASSERT_TRUE(phys.valid()) << phys.error();
  const int contact = 11;
  const Eigen::Vector2d F(-0.15, 0.25);  // millinewtons
  Eigen::VectorXd u_mm;
  const auto summary = press(phys, contact, F, u_mm);
  ASSERT_EQ(summary.status, common::StaticSolverStatus::kConverged);
  const double tip_turn_deg = std::abs(u_mm[3 * 16 + 2]) * 180.0 / M_PI;
  std::cout << "tip rotation " << tip_turn_deg << " deg\n";
  EXPECT_GT(tip_turn_deg, 20.0) << "meant to be a large deflection";

  // The same state in pixels, as the tracker would hold it.
  Eigen::VectorXd u_px = u_mm;
  for (int i = 0; i < phys.num_nodes(); ++i) u_px.segment<2>(3 * i) /= 0.05;
  WhiskerReadoutOptions o;
  o.physics = ph;
  const WhiskerReadoutModel readout(pixel_model(rest), o);
  ASSERT_TRUE(readout.valid()) << readout.error();
  const WhiskerReadout r = readout.evaluate(u_px);

  // In SI: F in newtons, the moment about the deformed follicle in newton-metres.
  const Eigen::Matrix2Xd x = phys.current_positions(u_mm) * 1e-3;
  const Eigen::Vector2d F_si = 1e-3 * F;
  const Eigen::Vector2d arm = x.col(contact) - x.col(0);
  const double m_expected = -(arm.x() * F_si.y() - arm.y() * F_si.x());
  std::cout << "M0 " << r.moment << " N m (expected " << m_expected << "), F0 "
            << r.force.transpose() << " N\n";
  EXPECT_NEAR(r.force.x(), -F_si.x(), 1e-6 * F_si.norm());
  EXPECT_NEAR(r.force.y(), -F_si.y(), 1e-6 * F_si.norm());
  // The moment from the first three elements' curvatures, extrapolated to the follicle: exact up
  // to the discretisation (measured 0.05 %).
  EXPECT_NEAR(r.moment, m_expected, 0.005 * std::abs(m_expected));
  // The first element's own load p (force and moment) balances to the solver's tolerance.
  EXPECT_NEAR(r.moment_first_element, m_expected, 1e-6 * std::abs(m_expected));
  // Axial and lateral are the same force in the base tangent's frame.
  EXPECT_NEAR(std::hypot(r.force_axial, r.force_lateral), F_si.norm(), 1e-9 * F_si.norm());
}

TEST(WhiskerReadout, TheSameWhiskerAtTwoImageScalesGivesTheSameSIFigures) {
  const Eigen::Matrix2Xd rest_a = arc_nodes({40.0, 80.0}, 0.2, 1.0 / 500.0, 160.0, 12);
  const Eigen::Matrix2Xd bent_a = arc_nodes({40.0, 80.0}, 0.35, 1.0 / 150.0, 160.0, 12);
  // Scale b: half the millimetres per pixel, so everything is twice as many pixels.
  const Eigen::Matrix2Xd rest_b = 2.0 * rest_a, bent_b = 2.0 * bent_a;
  auto state = [](const Eigen::Matrix2Xd& rest, const Eigen::Matrix2Xd& bent) {
    const Eigen::Matrix2Xd T = polyline_node_tangents(rest), t = polyline_node_tangents(bent);
    Eigen::VectorXd u(3 * rest.cols());
    for (int i = 0; i < rest.cols(); ++i) {
      u.segment<2>(3 * i) = bent.col(i) - rest.col(i);
      u[3 * i + 2] = std::atan2(T(0, i) * t(1, i) - T(1, i) * t(0, i), T.col(i).dot(t.col(i)));
    }
    return u;
  };
  WhiskerReadoutOptions oa, ob;
  oa.physics = rat_like(0.06);
  ob.physics = rat_like(0.03);
  ob.curvature_to_px = 2.0 * oa.curvature_to_px;
  const WhiskerReadoutModel ra(pixel_model(rest_a), oa), rb(pixel_model(rest_b), ob);
  ASSERT_TRUE(ra.valid() && rb.valid());
  const WhiskerReadout a = ra.evaluate(state(rest_a, bent_a)),
                       b = rb.evaluate(state(rest_b, bent_b));
  std::cout << "M0 " << a.moment << " / " << b.moment << " N m, curvature " << a.curvature << " / "
            << b.curvature << " 1/mm\n";
  EXPECT_NEAR(a.moment, b.moment, 1e-9 * std::abs(a.moment));
  EXPECT_NEAR(a.force_axial, b.force_axial, 1e-9 * a.force.norm());
  EXPECT_NEAR(a.force_lateral, b.force_lateral, 1e-9 * a.force.norm());
  EXPECT_NEAR(a.curvature, b.curvature, 1e-9 * std::abs(a.curvature));
  EXPECT_NEAR(a.base_angle_deg, b.base_angle_deg, 1e-9);
}

TEST(WhiskerReadout, CurvatureDeltaCurvatureAndBaseAngleOfExactArcs) {
  const double k_rest = 1.0 / 400.0, k_now = 1.0 / 120.0;
  const Eigen::Matrix2Xd rest = arc_nodes({60.0, 90.0}, 0.25, k_rest, 180.0, 15);
  const Eigen::Matrix2Xd bent = arc_nodes({60.0, 90.0}, 0.40, k_now, 180.0, 15);
  const Eigen::Matrix2Xd T = polyline_node_tangents(rest);
  Eigen::VectorXd u(3 * rest.cols());
  for (int i = 0; i < rest.cols(); ++i) {
    // The exact tangent of the bent arc at node i against the node's reference tangent.
    const double a = 0.40 + k_now * 180.0 * i / 15.0;
    u.segment<2>(3 * i) = bent.col(i) - rest.col(i);
    u[3 * i + 2] = a - std::atan2(T(1, i), T(0, i));
  }
  WhiskerReadoutOptions o;
  o.axis_angle_deg = 10.0;
  o.curvature_from_px = 5.0;
  o.curvature_to_px = 45.0;
  const WhiskerReadoutModel model(pixel_model(rest), o);
  ASSERT_TRUE(model.valid()) << model.error();
  const WhiskerReadout r = model.evaluate(u);
  std::cout << "curvature " << r.curvature << " (true " << k_now << "), rest "
            << model.rest_curvature() << " (true " << k_rest << "), base angle " << r.base_angle_deg
            << " deg\n";
  EXPECT_NEAR(r.curvature, k_now, 0.01 * k_now);
  EXPECT_NEAR(model.rest_curvature(), k_rest, 0.01 * k_rest);
  EXPECT_NEAR(r.delta_curvature, k_now - k_rest, 0.01 * (k_now - k_rest));
  EXPECT_NEAR(r.base_angle_deg, 0.40 * 180.0 / M_PI - 10.0, 1e-9);
  // Model units: the moment is the first element's EI times its curvature change, about.
  const double EI = model.base_section().EI;
  EXPECT_NEAR(r.moment, -EI * (k_now - k_rest), 0.1 * EI * (k_now - k_rest));
}

TEST(WhiskerContact, ClosestApproachToAPoleAlongTheWhisker) {
  // A straight whisker along y = 100 from x = 50; a pole of radius 8 whose surface is 1 px from
  // its centreline at x = 150. Within 3.5 px of the surface from x = 150 − √(11.5² − 9²) = 142.7
  // on; the contact point is the closest approach, x = 150.
  const std::vector<std::vector<Eigen::Vector2d>> init = {{{50.0, 100.0}, {250.0, 100.0}}};
  const WhiskerTracker tracker(init);
  ASSERT_TRUE(tracker.valid()) << tracker.error();
  const int width = 320, height = 200;
  auto pole_map = [&](const Eigen::Vector2d& centre, double radius) {
    std::vector<float> d(static_cast<std::size_t>(width) * height);
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) {
        d[static_cast<std::size_t>(y) * width + x] =
            static_cast<float>(std::max(0.0, (Eigen::Vector2d(x, y) - centre).norm() - radius));
      }
    }
    return d;
  };
  const auto touching = pole_map({150.0, 109.0}, 8.0);
  const WhiskerContact c = find_contact(tracker.whisker(0), touching.data(), width, height, 3.5);
  EXPECT_TRUE(c.touching);
  EXPECT_NEAR(c.arc_length_px, 100.0, 0.6);
  EXPECT_NEAR(c.point.x(), 150.0, 0.6);
  EXPECT_NEAR(c.distance_px, 1.0, 0.05);
  const auto apart = pole_map({150.0, 120.0}, 8.0);  // 12 px off the centreline
  const WhiskerContact none = find_contact(tracker.whisker(0), apart.data(), width, height, 3.5);
  EXPECT_FALSE(none.touching);
  EXPECT_NEAR(none.distance_px, 12.0, 0.05);
  EXPECT_FALSE(find_contact(tracker.whisker(0), nullptr, width, height).touching);
  // Away from the pole at the contact point: straight up from its centre below (−y), unit
  // length where the map is a distance; zero off the map or without one.
  const Eigen::Vector2d away = away_from_objects(touching.data(), width, height, c.point);
  EXPECT_NEAR(away.x(), 0.0, 0.1);
  EXPECT_NEAR(away.y(), -1.0, 0.02);
  EXPECT_EQ(away_from_objects(touching.data(), width, height, {-5.0, 50.0}),
            Eigen::Vector2d::Zero());
  EXPECT_EQ(away_from_objects(nullptr, width, height, c.point), Eigen::Vector2d::Zero());
}

// The contact load in SI (rt::contact_fit_beam with a scale): a tapered rat-like whisker pushed at
// 70 % of its length by a known force, solved in millimetres and millinewtons on its own 16
// elements (a large deflection), handed to the load fit in pixels, at two image scales (the same
// whisker in twice as many pixels). The fit's force along the known contact normal comes out in
// newtons and its moment about the follicle in newton-metres, the same at both scales.
TEST(WhiskerContactLoad, TaperedWhiskerGivesTheSameSIForceAtTwoImageScales) {
  const int elements = 16, contact = 11;
  const Eigen::Vector2d F(-0.05, 0.12);  // millinewtons
  Eigen::Vector2d forces[2];
  double moments[2] = {0.0, 0.0}, expected_moment = 0.0;
  const double scales[2] = {0.05, 0.025};  // mm per pixel
  for (int k = 0; k < 2; ++k) {
    const double mm_per_px = scales[k];
    const Eigen::Matrix2Xd rest =
        arc_nodes(Eigen::Vector2d(50.0, 100.0) * (0.05 / mm_per_px), 0.3,
                  1.0 / 600.0 * (mm_per_px / 0.05), 200.0 * (0.05 / mm_per_px), elements);
    const WhiskerPhysics ph = rat_like(mm_per_px);
    const common::BeamModel phys = physical_model(rest, ph);
    ASSERT_TRUE(phys.valid()) << phys.error();
    Eigen::VectorXd u;
    ASSERT_EQ(press(phys, contact, F, u).status, common::StaticSolverStatus::kConverged);
    if (k == 0) {
      const double tip_turn_deg = std::abs(u[3 * elements + 2]) * 180.0 / M_PI;
      std::cout << "tip rotation " << tip_turn_deg << " deg\n";
      EXPECT_GT(tip_turn_deg, 20.0) << "meant to be a large deflection";
      const Eigen::Matrix2Xd x = phys.current_positions(u);  // millimetres
      const double arm_x = 1e-3 * (x(0, contact) - x(0, 0)),
                   arm_y = 1e-3 * (x(1, contact) - x(1, 0));
      expected_moment = 1e-3 * (arm_x * F.y() - arm_y * F.x());
    }
    for (int i = 0; i < phys.num_nodes(); ++i) u.segment<2>(3 * i) /= mm_per_px;  // → pixels

    // The tracked beam: the rest shape in pixels with any section (the fit replaces it).
    auto d = common::BeamDescription::uniform(
        rest, common::BeamMaterial{1000.0, 1000.0 / 2.6, 2.0, 2.0 / 3.0});
    const common::BeamModel tracked(d);
    LoadFitOptions lo;
    lo.max_load_points = 1;
    lo.max_iterations = 20;
    LoadFit fit(contact_fit_beam(tracked, Eigen::VectorXd::Zero(tracked.num_dofs()), ph), lo);
    ASSERT_TRUE(fit.valid()) << fit.error();
    const int point = fit.fine_node(contact);
    const Eigen::Vector2d n = F.normalized();
    const double direction[2] = {n.x(), n.y()};
    const LoadFitSummary summary = fit.fit(u, &point, 1, direction);
    EXPECT_TRUE(summary.converged) << "scale " << mm_per_px;
    forces[k] = fit.loads()[0] * n;  // newtons
    const Eigen::Matrix2Xd& X = fit.model().rest_positions();
    const Eigen::Vector2d arm =
        (X.col(point) + fit.state().segment<2>(3 * point) - X.col(0) - fit.state().segment<2>(0)) *
        (mm_per_px * 1e-3);
    moments[k] = arm.x() * forces[k].y() - arm.y() * forces[k].x();
    std::cout << mm_per_px << " mm/px: force " << forces[k].transpose() << " N (applied "
              << 1e-3 * F.transpose() << "), moment " << moments[k] << " N m (expected "
              << expected_moment << "), misfit " << summary.rms_px << " px\n";
  }
  // Against the truth, to what the fit's 4× subdivided beam makes of the 16-element solve.
  for (int k = 0; k < 2; ++k) {
    EXPECT_LT((forces[k] - 1e-3 * F).norm(), 0.01 * 1e-3 * F.norm()) << "scale " << scales[k];
    EXPECT_NEAR(moments[k], expected_moment, 0.01 * std::abs(expected_moment));
  }
  // Unit consistency: the two scales agree to 1 %.
  EXPECT_LT((forces[0] - forces[1]).norm(), 0.01 * forces[0].norm());
  EXPECT_NEAR(moments[0], moments[1], 0.01 * std::abs(moments[0]));
}

TEST(WhiskerReadout, BadOptionsAreNamed) {
  const Eigen::Matrix2Xd rest = arc_nodes({0.0, 0.0}, 0.0, 0.0, 100.0, 8);
  WhiskerReadoutOptions o;
  o.physics.mm_per_px = 0.05;  // a scale without a radius
  const WhiskerReadoutModel m(pixel_model(rest), o);
  EXPECT_FALSE(m.valid());
  EXPECT_NE(m.error().find("base_radius_um"), std::string::npos) << m.error();
  WhiskerReadoutOptions o2;
  o2.curvature_from_px = 150.0;
  o2.curvature_to_px = 160.0;
  const WhiskerReadoutModel m2(pixel_model(rest), o2);
  EXPECT_FALSE(m2.valid());
  EXPECT_NE(m2.error().find("beyond the whisker"), std::string::npos) << m2.error();
}

// The rat C2 preset: the literature's values (readout.hpp names the sources), a valid whisker once
// a scale is given, E·I = E·π·r⁴/4 at its follicle and its tip; other names are unknown.
TEST(WhiskerPreset, RatC2IsATaperedConeOfTheLiteraturesSize) {
  const auto rat = whisker_preset("rat-c2");
  ASSERT_TRUE(rat.has_value());
  EXPECT_EQ(rat->young_modulus_gpa, 3.34);
  EXPECT_EQ(rat->base_radius_um, 69.5);
  EXPECT_EQ(rat->tip_radius_um, 1.6);
  EXPECT_EQ(rat->length_mm, 33.6);
  EXPECT_EQ(rat->mm_per_px, 0.0);  // the camera's, not the whisker's
  WhiskerPhysics scaled = *rat;
  scaled.mm_per_px = 0.05;
  EXPECT_FALSE(scaled.validate().has_value());
  const double base_ei = 3.34e9 * M_PI * std::pow(69.5e-6, 4) / 4.0;  // about 6.1e-8 N·m²
  const double tip_ei = 3.34e9 * M_PI * std::pow(1.6e-6, 4) / 4.0;
  EXPECT_NEAR(scaled.section_at(0.0, 0.0).EI, base_ei, 1e-9 * base_ei);
  EXPECT_NEAR(scaled.section_at(33.6, 0.0).EI, tip_ei, 1e-9 * tip_ei);
  const double mid_radius = 0.5 * (69.5e-6 + 1.6e-6);
  const double mid_ei = 3.34e9 * M_PI * std::pow(mid_radius, 4) / 4.0;
  EXPECT_NEAR(scaled.section_at(16.8, 0.0).EI, mid_ei, 1e-9 * mid_ei);
  EXPECT_FALSE(whisker_preset("mouse").has_value());
  EXPECT_FALSE(whisker_preset("").has_value());
  EXPECT_EQ(whisker_preset_names(), (std::vector<std::string>{"rat-c2", "mouse-c2"}));
}

// The mouse C2 preset: its sourced length and radii, the rat's modulus (none is measured in mice),
// and E·I of its cone at the follicle, the middle and the tip; about (33.5 / 69.5)⁴ ≈ 1/19 of the
// rat's at the follicle.
TEST(WhiskerPreset, MouseC2IsAThinnerShorterConeWithTheRatsModulus) {
  const auto mouse = whisker_preset("mouse-c2");
  const auto rat = whisker_preset("rat-c2");
  ASSERT_TRUE(mouse.has_value() && rat.has_value());
  EXPECT_EQ(mouse->young_modulus_gpa, rat->young_modulus_gpa);
  EXPECT_EQ(mouse->base_radius_um, 33.5);
  EXPECT_EQ(mouse->tip_radius_um, 1.5);
  EXPECT_EQ(mouse->length_mm, 13.2);
  EXPECT_EQ(mouse->mm_per_px, 0.0);
  WhiskerPhysics scaled = *mouse;
  scaled.mm_per_px = 0.02;
  EXPECT_FALSE(scaled.validate().has_value());
  const auto ei = [](double radius_m) { return 3.34e9 * M_PI * std::pow(radius_m, 4) / 4.0; };
  EXPECT_NEAR(scaled.section_at(0.0, 0.0).EI, ei(33.5e-6), 1e-9 * ei(33.5e-6));
  EXPECT_NEAR(scaled.section_at(6.6, 0.0).EI, ei(17.5e-6), 1e-9 * ei(17.5e-6));
  EXPECT_NEAR(scaled.section_at(13.2, 0.0).EI, ei(1.5e-6), 1e-9 * ei(1.5e-6));
  WhiskerPhysics rat_scaled = *rat;
  rat_scaled.mm_per_px = 0.02;
  const double ratio = scaled.section_at(0.0, 0.0).EI / rat_scaled.section_at(0.0, 0.0).EI;
  EXPECT_NEAR(ratio, std::pow(33.5 / 69.5, 4), 1e-9);
  EXPECT_LT(ratio, 1.0 / 18.0);
}

}  // namespace
}  // namespace sinew::rt
