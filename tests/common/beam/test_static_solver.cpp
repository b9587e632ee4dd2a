// The static beam solver against exact elastica solutions (../shared/reference/beam_benchmarks.md):
// cantilever with a tip dead load λ = PL²/EI, and pure bending up to a full circle, for straight
// beams along x, rotated by arbitrary angles, and with unequal element lengths.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <string>

#include <Eigen/Geometry>

#include "common/beam/static_solver.hpp"

namespace sinew::common {
namespace {

constexpr double kPi = 3.14159265358979323846;

struct TipLoadRow {
  double lambda, v, shortening, theta;
};

// Section 1 of the reference file; empty when ../shared is absent.
std::vector<TipLoadRow> read_tip_load_table() {
  std::ifstream in(std::string(SINEW_SHARED_DIR) + "/reference/beam_benchmarks.md");
  std::vector<TipLoadRow> rows;
  std::string line;
  bool in_section = false;
  while (std::getline(in, line)) {
    if (line.rfind("## ", 0) == 0) in_section = line.rfind("## 1.", 0) == 0;
    if (!in_section || line.rfind("| ", 0) != 0) continue;
    std::replace(line.begin(), line.end(), '|', ' ');
    std::istringstream s(line);
    TipLoadRow r;
    if (s >> r.lambda >> r.v >> r.shortening >> r.theta) rows.push_back(r);
  }
  return rows;
}

// A cantilever of length 1 from the origin along `angle`, nodes at arc lengths s (0 = s₀ < … = 1),
// EI = 1, EA = GA = 1e6 (EA·L²/EI = 1e6: inextensible and unshearable to within ~1e-5).
BeamModel cantilever(const std::vector<double>& s, double angle) {
  Eigen::Matrix2Xd X(2, s.size());
  for (std::size_t i = 0; i < s.size(); ++i)
    X.col(i) << s[i] * std::cos(angle), s[i] * std::sin(angle);
  BeamMaterial m{1e6, 1e6, 1.0, 1e-6};
  BeamDescription d = BeamDescription::uniform(X, m);
  d.clamp(0);
  return BeamModel(d);
}

std::vector<double> equal_spacing(int elements) {
  std::vector<double> s(elements + 1);
  for (int i = 0; i <= elements; ++i) s[i] = double(i) / elements;
  return s;
}

std::vector<double> unequal_spacing(int elements) {
  // Lengths growing by a factor ~2 along the beam, plus a deterministic ±20 % jitter (the shortest
  // and longest differ by ~2.6x).
  std::vector<double> s(elements + 1, 0.0);
  for (int i = 1; i <= elements; ++i) {
    s[i] = s[i - 1] + 1.0 + 1.0 * i / elements + 0.3 * std::sin(7.0 * i);
  }
  for (auto& v : s) v /= s.back();
  return s;
}

// Tip state in the beam's own frame (x along the reference axis): x, y and rotation.
Eigen::Vector3d solve_tip(const BeamModel& model, double angle, const Eigen::Vector3d& local_load,
                          int steps, StaticSolverSummary* summary_out = nullptr) {
  const int n = model.num_nodes();
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * n);
  const Eigen::Rotation2Dd R(angle);
  f.segment<2>(3 * (n - 1)) = R * local_load.head<2>();
  f[3 * n - 1] = local_load[2];
  Eigen::VectorXd u = Eigen::VectorXd::Zero(3 * n);
  StaticSolverOptions options;
  options.load_steps = steps;
  StaticBeamSolver solver(model, options);
  const StaticSolverSummary summary = solver.solve(f, u);
  if (summary_out) *summary_out = summary;
  EXPECT_TRUE(summary.converged()) << summary.full_report();
  const Eigen::Vector2d tip = R.inverse() * model.current_positions(u).col(n - 1);
  return {tip.x(), tip.y(), u[3 * n - 1]};
}

TEST(StaticBeamSolver, CantileverTipLoadMatchesElastica) {
  const auto table = read_tip_load_table();
  if (table.empty()) GTEST_SKIP() << "../shared/reference/beam_benchmarks.md not found";
  int checked = 0;
  for (const auto& row : table) {
    const bool required = row.lambda == 1 || row.lambda == 3 || row.lambda == 10;
    for (double angle : {0.0, 0.7, 2.9, -2.2}) {
      for (bool unequal : {false, true}) {
        if (!required && (angle != 0.0 || unequal)) continue;
        const auto s = unequal ? unequal_spacing(20) : equal_spacing(20);
        const BeamModel model = cantilever(s, angle);
        const int steps = row.lambda < 2 ? 1 : int(std::ceil(4 * row.lambda));
        const Eigen::Vector3d tip = solve_tip(model, angle, {0, row.lambda, 0}, steps);
        SCOPED_TRACE("lambda " + std::to_string(row.lambda) + " angle " + std::to_string(angle) +
                     (unequal ? " unequal" : " equal"));
        EXPECT_NEAR(tip.x(), 1.0 - row.shortening, 2e-3);
        EXPECT_NEAR(tip.y(), row.v, 2e-3);
        EXPECT_NEAR(tip.z(), row.theta, 2e-3);
        ++checked;
      }
    }
  }
  EXPECT_GE(checked, 3 * 8);
}

TEST(StaticBeamSolver, EndMomentRollsIntoCircle) {
  // Pure bending is exact for this element: constant curvature, the nodes on a circle.
  for (double angle : {0.0, 1.3, -2.8}) {
    for (bool unequal : {false, true}) {
      const auto s = unequal ? unequal_spacing(20) : equal_spacing(20);
      const BeamModel model = cantilever(s, angle);
      for (double turns : {0.25, 0.5, 0.75, 1.0}) {
        const double theta = 2 * kPi * turns;  // M·L/EI
        SCOPED_TRACE("theta " + std::to_string(theta) + " angle " + std::to_string(angle));
        const Eigen::Vector3d tip = solve_tip(model, angle, {0, 0, theta}, 20);
        // u/L = sin θ/θ − 1, v/L = (1 − cos θ)/θ; the tip x is 1 + u/L.
        EXPECT_NEAR(tip.x(), std::sin(theta) / theta, 1e-3);
        EXPECT_NEAR(tip.y(), (1 - std::cos(theta)) / theta, 1e-3);
        EXPECT_NEAR(tip.z(), theta, 1e-6);
        if (turns == 1.0) {
          EXPECT_LT(tip.head<2>().norm(), 1e-3) << "full circle closes";
        }
      }
    }
  }
}

TEST(StaticBeamSolver, CutsStepsWhenOneIncrementIsTooLarge) {
  const BeamModel model = cantilever(equal_spacing(20), 0.0);
  StaticSolverSummary summary;
  const Eigen::Vector3d tip = solve_tip(model, 0.0, {0, 10.0, 0}, 1, &summary);
  EXPECT_NEAR(tip.y(), 0.810609, 2e-3);
  EXPECT_GT(summary.step_cuts, 0) << summary.brief_report();
}

TEST(StaticBeamSolver, FreeBeamIsReportedSingular) {
  Eigen::Matrix2Xd X(2, 3);
  X << 0, 1, 2, 0, 0, 0;
  BeamDescription d = BeamDescription::uniform(X, {1, 1, 1, 1});
  d.fix(0, BeamDof::kUx);
  d.fix(0, BeamDof::kUy);  // rotation about node 0 still free
  const BeamModel model(d);
  StaticBeamSolver solver(model);
  Eigen::VectorXd u = Eigen::VectorXd::Zero(9), f = Eigen::VectorXd::Zero(9);
  f[7] = 1.0;
  const auto summary = solver.solve(f, u);
  EXPECT_EQ(summary.status, StaticSolverStatus::kSingularSystem);
  EXPECT_NE(std::string(summary.message).find("rigid"), std::string::npos);
}

// Midspan deflection of a simply supported beam (pins at both ends, rotations free) under a small
// midspan load P, relative to linear theory PL³/(48EI) + PL/(4GA).
double pinned_midspan_error(int elements) {
  const int n = elements + 1;
  Eigen::Matrix2Xd X(2, n);
  for (int i = 0; i < n; ++i) X.col(i) << double(i) / (n - 1), 0.0;
  BeamDescription d = BeamDescription::uniform(X, {1e6, 1e6, 1.0, 1e-6});
  d.fix(0, BeamDof::kUx);
  d.fix(0, BeamDof::kUy);
  d.fix(n - 1, BeamDof::kUy);
  const BeamModel model(d);
  StaticBeamSolver solver(model);
  Eigen::VectorXd u = Eigen::VectorXd::Zero(3 * n), f = Eigen::VectorXd::Zero(3 * n);
  const double P = 1e-3;
  f[3 * (n / 2) + 1] = -P;
  EXPECT_TRUE(solver.solve(f, u).converged());
  const double exact = -P / 48.0 - P / 4e6;
  return std::abs(u[3 * (n / 2) + 1] - exact) / std::abs(exact);
}

TEST(StaticBeamSolver, PinnedBeamConvergesQuadraticallyToLinearTheory) {
  // One-point (reduced) integration of linear elements: O(h²) in the deflection.
  const double e20 = pinned_midspan_error(20), e40 = pinned_midspan_error(40);
  EXPECT_LT(e20, 5e-3);
  EXPECT_LT(e40, 1.5e-3);
  EXPECT_NEAR(e20 / e40, 4.0, 0.4) << "errors " << e20 << ", " << e40;
}

TEST(StaticBeamSolver, RejectsInvalidOptionsAndSizes) {
  const BeamModel model = cantilever(equal_spacing(4), 0.0);
  StaticSolverOptions bad;
  bad.load_steps = 0;
  ASSERT_TRUE(bad.validate().has_value());
  EXPECT_NE(bad.validate()->find("load_steps"), std::string::npos);
  StaticBeamSolver solver(model, bad);
  Eigen::VectorXd u = Eigen::VectorXd::Zero(15), f = Eigen::VectorXd::Zero(15);
  EXPECT_EQ(solver.solve(f, u).status, StaticSolverStatus::kInvalidInput);
  StaticBeamSolver good(model);
  Eigen::VectorXd wrong = Eigen::VectorXd::Zero(14);
  EXPECT_EQ(good.solve(wrong, u).status, StaticSolverStatus::kInvalidInput);
  f[14] = std::nan("");
  EXPECT_EQ(good.solve(f, u).status, StaticSolverStatus::kNonFinite);
}

}  // namespace
}  // namespace sinew::common
