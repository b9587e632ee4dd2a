#include "tools/synth/scenario.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "common/beam/static_solver.hpp"

namespace sinew::tools::synth {

namespace {

constexpr double kPi = 3.14159265358979323846;

/// A rectangular section of height h = 2·half_width and depth 1 (pixel units): E = 1000,
/// A = h, I = h³/12, G = E/2.6 (ν = 0.3). EA·L²/EI = 12 (L/h)² ≈ 1e4–1e5: nearly inextensible.
common::BeamMaterial pixel_material(double half_width) {
  const double h = 2.0 * half_width;
  common::BeamMaterial m;
  m.E = 1000.0;
  m.G = m.E / 2.6;
  m.A = h;
  m.I = h * h * h / 12.0;
  return m;
}

Eigen::Matrix2d rotation(double angle) {
  Eigen::Matrix2d R;
  R << std::cos(angle), -std::sin(angle), std::sin(angle), std::cos(angle);
  return R;
}

/// Fills the tracker's view of frame `frame` from the fine state: positions and θ at fine nodes
/// kSubdivision·k.
void sample_tracker_nodes(const common::BeamModel& fine, const Eigen::VectorXd& u,
                          FrameTruth& truth) {
  const int n = (fine.num_nodes() - 1) / kSubdivision;
  truth.centreline = fine.current_positions(u);
  truth.nodes.resize(3, n + 1);
  for (int k = 0; k <= n; ++k) {
    const int j = kSubdivision * k;
    truth.nodes.col(k) << truth.centreline(0, j), truth.centreline(1, j), u[3 * j + 2];
  }
}

[[noreturn]] void solver_failed(int frame, double lambda,
                                const common::StaticSolverSummary& summary) {
  std::ostringstream s;
  s << "the beam solver did not converge at frame " << frame << " (lambda " << lambda
    << "): " << summary.brief_report() << "; try a smaller --lambda-max or more --frames";
  throw std::runtime_error(s.str());
}

common::StaticSolverOptions solver_options(double lambda_increment) {
  common::StaticSolverOptions o;
  // About four increments per unit of λ (as sinew-simulate), at least two per frame.
  o.load_steps = std::max(2, static_cast<int>(std::ceil(4.0 * std::abs(lambda_increment))));
  o.max_iterations_per_step = 40;
  o.max_step_cuts = 20;
  return o;
}

// ---------------------------------------------------------------------------------------------
// cantilever: straight, clamped at node 0 near (0.2 W, 0.3 H), pointing right and tilted 3° up;
// dead tip load P = λ·EI/L² along the reference normal (image +y, down), λ = λ_max·k/(N − 1).

Simulation simulate_cantilever(const SynthOptions& o) {
  const int n = o.elements, nf = kSubdivision * n;
  const double L = 0.6 * o.width;
  const Eigen::Vector2d base(0.2 * o.width, 0.3 * o.height);
  const double tilt = -3.0 * kPi / 180.0;
  const Eigen::Vector2d tangent(std::cos(tilt), std::sin(tilt));
  const Eigen::Vector2d normal(-tangent.y(), tangent.x());  // R(π/2)·t: bending towards +y

  Eigen::Matrix2Xd fine_rest(2, nf + 1);
  for (int j = 0; j <= nf; ++j) fine_rest.col(j) = base + tangent * (L * j / nf);

  Simulation sim;
  sim.length = L;
  sim.beam.material = pixel_material(o.half_width_px);
  sim.beam.clamped_base = true;
  sim.beam.load_nodes = {n};
  sim.beam.rest_positions.resize(2, n + 1);
  for (int k = 0; k <= n; ++k) sim.beam.rest_positions.col(k) = fine_rest.col(kSubdivision * k);

  common::BeamDescription description =
      common::BeamDescription::uniform(fine_rest, sim.beam.material);
  description.clamp(0);
  const common::BeamModel model(description);
  if (!model.valid()) throw std::runtime_error("internal: invalid beam model: " + model.error());

  const double EI = sim.beam.material.E * sim.beam.material.I;
  Eigen::VectorXd u = Eigen::VectorXd::Zero(model.num_dofs());
  Eigen::VectorXd loads = u, previous_loads = u;
  double previous_lambda = 0.0;
  for (int k = 0; k < o.frames; ++k) {
    FrameTruth truth;
    truth.lambda = o.lambda_max * k / (o.frames - 1);
    const double P = truth.lambda * EI / (L * L);
    loads.setZero();
    loads.segment<2>(3 * nf) = P * normal;
    // Warm start: u is in equilibrium with the previous frame's loads.
    common::StaticBeamSolver solver(model, solver_options(truth.lambda - previous_lambda));
    const common::StaticSolverSummary summary = solver.solve(loads, u, &previous_loads);
    if (!summary.converged()) solver_failed(k, truth.lambda, summary);
    truth.solver_iterations = summary.iterations;
    previous_loads = loads;
    previous_lambda = truth.lambda;

    sample_tracker_nodes(model, u, truth);
    truth.loads = Eigen::Matrix3Xd::Zero(3, n + 1);
    truth.loads.col(n) << P * normal.x(), P * normal.y(), 0.0;
    sim.frames.push_back(std::move(truth));
  }
  return sim;
}

// ---------------------------------------------------------------------------------------------
// free_curved: a whisker-like curve whose curvature falls linearly from base to tip,
// κ(s) = κ₀(1.8 − 2 s/L), so the tangent turns by 60° in all (κ₀L = 1.309) and the last tenth bends
// slightly back (a gentle S); tracker element lengths fall linearly from 2 to 1 (relative) from
// base to tip.

Eigen::Vector2d curve_point(double s, double L) {
  // Composite Simpson on x(s) = ∫₀ˢ (cos θ, sin θ); the integrand is smooth, 256 intervals give
  // ~1e-12·L.
  auto tangent = [L](double t) {
    const double kappa0 = (kPi / 3.0) / (0.8 * L);
    const double a = kappa0 * (1.8 * t - t * t / L);
    return Eigen::Vector2d(std::cos(a), std::sin(a));
  };
  const int m = 256;
  const double h = s / m;
  Eigen::Vector2d sum = tangent(0.0) + tangent(s);
  for (int i = 1; i < m; ++i) sum += (i % 2 ? 4.0 : 2.0) * tangent(i * h);
  return sum * (h / 3.0);
}

/// The three forces (all along `direction`) at fine nodes 0, mid and end, with the middle one
/// P·direction and the end ones chosen so that the set has zero resultant force and zero moment
/// about any point in the configuration x (dead loads balanced in the current, deformed state).
void balanced_three_point_loads(const Eigen::Matrix2Xd& x, int mid, double P,
                                const Eigen::Vector2d& direction, Eigen::VectorXd& loads) {
  const int end = static_cast<int>(x.cols()) - 1;
  // Moment of F·direction applied at p: F·(p × direction) = F·(p · arm).
  const Eigen::Vector2d arm(direction.y(), -direction.x());
  const double s0 = x.col(0).dot(arm), sm = x.col(mid).dot(arm), se = x.col(end).dot(arm);
  const double F0 = -P * (se - sm) / (se - s0);
  const double Fe = -P * (sm - s0) / (se - s0);
  loads.setZero();
  loads.segment<2>(0) = F0 * direction;
  loads.segment<2>(3 * mid) = P * direction;
  loads.segment<2>(3 * end) = Fe * direction;
}

Simulation simulate_free_curved(const SynthOptions& o) {
  const int n = o.elements, nf = kSubdivision * n;
  const double L = 0.6 * o.width;

  // Tracker knots at arc lengths with element lengths ∝ 2 − k/(n − 1); fine nodes split each
  // tracker element into kSubdivision equal arcs.
  std::vector<double> knots(n + 1, 0.0);
  for (int k = 0; k < n; ++k) knots[k + 1] = knots[k] + 2.0 - static_cast<double>(k) / (n - 1);
  for (double& s : knots) s *= L / knots[n];
  Eigen::Matrix2Xd fine_rest(2, nf + 1);
  for (int k = 0; k < n; ++k) {
    for (int i = 0; i < kSubdivision; ++i) {
      const double s = knots[k] + (knots[k + 1] - knots[k]) * i / kSubdivision;
      fine_rest.col(kSubdivision * k + i) = curve_point(s, L);
    }
  }
  fine_rest.col(nf) = curve_point(L, L);
  // Base on the left, end-to-end chord horizontal, bounding box centred in the image.
  const Eigen::Vector2d chord = fine_rest.col(nf) - fine_rest.col(0);
  fine_rest = rotation(-std::atan2(chord.y(), chord.x())) * fine_rest;
  const Eigen::Vector2d box_centre =
      0.5 * (fine_rest.rowwise().minCoeff() + fine_rest.rowwise().maxCoeff());
  fine_rest.colwise() += Eigen::Vector2d(0.5 * o.width, 0.5 * o.height) - box_centre;

  Simulation sim;
  sim.length = L;
  sim.beam.material = pixel_material(o.half_width_px);
  sim.beam.clamped_base = false;
  sim.beam.rest_positions.resize(2, n + 1);
  for (int k = 0; k <= n; ++k) sim.beam.rest_positions.col(k) = fine_rest.col(kSubdivision * k);

  // The solver clamps node 0 only to remove the rigid motions; the loads are balanced in the
  // deformed state, so its reaction is zero.
  common::BeamDescription description =
      common::BeamDescription::uniform(fine_rest, sim.beam.material);
  description.clamp(0);
  const common::BeamModel model(description);
  if (!model.valid()) throw std::runtime_error("internal: invalid beam model: " + model.error());

  // Forces perpendicular to the end-to-end chord; the middle one pushes towards the convex side
  // (away from the chord), increasing the curvature.
  const int mid_tracker = n / 2, mid = kSubdivision * mid_tracker;
  const Eigen::Vector2d ends = fine_rest.col(nf) - fine_rest.col(0);
  Eigen::Vector2d direction(-ends.y(), ends.x());
  direction.normalize();
  if ((fine_rest.col(mid) - fine_rest.col(0)).dot(direction) < 0.0) direction = -direction;

  const double EI = sim.beam.material.E * sim.beam.material.I;
  const double force_scale = EI / (L * L);
  const Eigen::Vector2d centroid = fine_rest.rowwise().mean();
  Eigen::VectorXd u = Eigen::VectorXd::Zero(model.num_dofs());
  Eigen::VectorXd loads = u, previous_loads = u;
  double previous_lambda = 0.0;
  for (int k = 0; k < o.frames; ++k) {
    FrameTruth truth;
    // Loading then partial unloading: peak at two thirds of the sequence, 0.71·λ_max at the end.
    truth.lambda = o.lambda_max * std::sin(0.75 * kPi * k / (o.frames - 1));
    const double P = truth.lambda * force_scale;
    // Fixed point on the load set: balance it in the current state, solve, repeat. The balance
    // depends on the deformation only through the nodes' positions along the chord, so a few
    // rounds reach 1e-12.
    common::StaticBeamSolver solver(model, solver_options(truth.lambda - previous_lambda));
    bool balanced = false;
    for (int round = 0; round < 50 && !balanced; ++round) {
      balanced_three_point_loads(model.current_positions(u), mid, P, direction, loads);
      if (round > 0 && (loads - previous_loads).lpNorm<Eigen::Infinity>() <= 1e-12 * force_scale) {
        balanced = true;
        break;
      }
      const common::StaticSolverSummary summary = solver.solve(loads, u, &previous_loads);
      if (!summary.converged()) solver_failed(k, truth.lambda, summary);
      truth.solver_iterations += summary.iterations;
      previous_loads = loads;
    }
    if (!balanced) {
      std::ostringstream s;
      s << "the free_curved load set could not be balanced at frame " << k << " (lambda "
        << truth.lambda << "); try a smaller --lambda-max";
      throw std::runtime_error(s.str());
    }
    previous_lambda = truth.lambda;
    sample_tracker_nodes(model, u, truth);
    truth.loads = Eigen::Matrix3Xd::Zero(3, n + 1);
    for (int t = 0; t <= n; ++t) {
      truth.loads.col(t).head<2>() = previous_loads.segment<2>(3 * kSubdivision * t);
      truth.loads(2, t) = previous_loads[3 * kSubdivision * t + 2];
    }

    // Slow rigid motion of the whole scene object (bounded for long sequences): rotation
    // 10°·sin(0.05 k) about the reference centroid (at most 0.5°/frame) and translation
    // (40 sin(0.05 k), 25 (1 − cos(0.05 k))) px (at most 2 px/frame). x ↦ x + (R − I)(x − c) + t
    // is exactly x on frame 0.
    const double phi = (10.0 * kPi / 180.0) * std::sin(0.05 * k);
    const Eigen::Vector2d shift(40.0 * std::sin(0.05 * k), 25.0 * (1.0 - std::cos(0.05 * k)));
    const Eigen::Matrix2d R = rotation(phi);
    const Eigen::Matrix2d R_minus_I = R - Eigen::Matrix2d::Identity();
    auto move = [&](Eigen::Matrix2Xd& x) {
      const Eigen::Matrix2Xd relative = x.colwise() - centroid;
      x += R_minus_I * relative;
      x.colwise() += shift;
    };
    move(truth.centreline);
    Eigen::Matrix2Xd xy = truth.nodes.topRows<2>();
    move(xy);
    truth.nodes.topRows<2>() = xy;
    truth.nodes.row(2).array() += phi;
    truth.loads.topRows<2>() = R * truth.loads.topRows<2>();
    sim.frames.push_back(std::move(truth));
  }
  return sim;
}

}  // namespace

Simulation simulate(const SynthOptions& options) {
  switch (options.scenario) {
    case Scenario::kCantilever:
      return simulate_cantilever(options);
    case Scenario::kFreeCurved:
      return simulate_free_curved(options);
  }
  throw std::logic_error("unknown scenario");
}

Eigen::Matrix3d camera_homography(const SynthOptions& options, int frame) {
  if (options.camera_motion == CameraMotion::kNone || frame == 0) {
    return Eigen::Matrix3d::Identity();
  }
  // About the image centre c: H = T(c)·M·T(−c) with M a rotation growing linearly to 3° on the
  // last frame, a bounded hand-held pan (at most 2 px/frame in x, 1 px/frame in y) and a
  // perspective row growing to 1e-5/px.
  const double progress = static_cast<double>(frame) / (options.frames - 1);
  const double angle = (3.0 * kPi / 180.0) * progress;
  const Eigen::Vector2d pan(30.0 * std::sin(frame / 15.0), 20.0 * std::sin(frame / 20.0));
  Eigen::Matrix3d M = Eigen::Matrix3d::Identity();
  M.topLeftCorner<2, 2>() = rotation(angle);
  M.topRightCorner<2, 1>() = pan;
  M(2, 0) = 1e-5 * progress;
  M(2, 1) = -0.6e-5 * progress;
  const Eigen::Vector2d c(0.5 * (options.width - 1), 0.5 * (options.height - 1));
  Eigen::Matrix3d to_centre = Eigen::Matrix3d::Identity(), back = Eigen::Matrix3d::Identity();
  to_centre.topRightCorner<2, 1>() = -c;
  back.topRightCorner<2, 1>() = c;
  const Eigen::Matrix3d H = back * M * to_centre;
  return H / H(2, 2);
}

std::optional<std::string> check_beam_inside_image(const SynthOptions& options,
                                                   const Simulation& simulation) {
  const double margin = options.half_width_px + 4.0;
  for (int k = 0; k < static_cast<int>(simulation.frames.size()); ++k) {
    const Eigen::Matrix3d H = camera_homography(options, k);
    const Eigen::Matrix2Xd& x = simulation.frames[k].centreline;
    for (Eigen::Index j = 0; j < x.cols(); ++j) {
      const Eigen::Vector3d q = H * Eigen::Vector3d(x(0, j), x(1, j), 1.0);
      const double px = q.x() / q.z(), py = q.y() / q.z();
      if (px < margin || py < margin || px > options.width - 1 - margin ||
          py > options.height - 1 - margin) {
        std::ostringstream s;
        s << "--width/--height " << options.width << "x" << options.height
          << ": the beam does not fit in the image with a " << margin << " px margin at frame " << k
          << " (point (" << px << ", " << py << ")); use a larger image, a smaller --lambda-max "
          << "or a smaller --half-width-px";
        return s.str();
      }
    }
  }
  return std::nullopt;
}

}  // namespace sinew::tools::synth
