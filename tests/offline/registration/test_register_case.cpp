// offline::register_case called directly (no sinew-register process) on the demo case of
// scripts/demo (tools/register/demo_case.hpp: a capsule attached at one end, its free part
// stretched and bent by a known deformation, ICP markers on the deformed surface): the result
// surface must be near the known truth, the markers met, the tets not inverted, and the figures
// sinew-register reports must be there. The same bounds as the tool's end-to-end test
// (tests/tools/test_sinew_register.cpp, DemoCaseMeetsItsKnownDeformation).
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "offline/registration/register_case.hpp"
#include "offline/registration/surface_distance.hpp"
#include "tests/support/run_tool.hpp"
#include "tools/register/case_file.hpp"
#include "tools/register/demo_case.hpp"

namespace {

using sinew::offline::io::SurfaceMesh;

// The demo case of scripts/demo written into a scratch folder and read back as sinew-register
// reads it.
struct DemoCaseFiles {
  sinew::tools::DemoCase demo;
  sinew::offline::RegistrationCase c;
};

DemoCaseFiles demo_case_in(const std::string& folder) {
  const auto dir = sinew::testing::scratch_dir(folder);
  DemoCaseFiles files{sinew::tools::make_demo_case(), {}};
  sinew::tools::write_demo_case(files.demo, dir.string());
  files.c = sinew::tools::read_registration_case((dir / "case.json").string());
  return files;
}

TEST(RegisterCase, DemoCaseMeetsItsKnownDeformation) {
  const DemoCaseFiles files = demo_case_in("register_case_demo");
  const sinew::tools::DemoCase& demo = files.demo;
  const sinew::offline::RegistrationCase& c = files.c;

  std::vector<std::string> messages;
  int iterations = 0, checkpoints = 0, prepared = 0;
  sinew::offline::RegisterCaseHooks hooks;
  hooks.message = [&](const std::string& line) { messages.push_back(line); };
  hooks.prepared = [&](const sinew::offline::PreparedCase& p) {
    ++prepared;
    EXPECT_FALSE(p.free_object);
    EXPECT_EQ(p.constraints.icp_markers.size(), static_cast<std::size_t>(demo.markers.rows()));
    EXPECT_EQ(p.constraints.attachments.size(),
              static_cast<std::size_t>(demo.attachment_points.rows()));
  };
  hooks.iteration = [&](const sinew::offline::GaussNewtonIteration&) { ++iterations; };
  hooks.checkpoint = [&](const sinew::offline::GaussNewtonCheckpoint&) { ++checkpoints; };
  const sinew::offline::RegisterCaseResult r = sinew::offline::register_case(c, {}, hooks);

  EXPECT_EQ(prepared, 1);
  EXPECT_GT(iterations, 0);
  EXPECT_GT(checkpoints, 0);
  EXPECT_FALSE(messages.empty());
  const sinew::offline::GaussNewtonSummary& summary = r.registration.summary;
  ASSERT_TRUE(summary.usable()) << sinew::offline::to_string(summary.termination) << " "
                                << summary.message;
  ASSERT_TRUE(r.shape.has_value());
  const double diagonal = r.problem.frame.scale;
  EXPECT_NEAR(diagonal, r.inputs.bounding_box_diagonal, 0.0);
  EXPECT_EQ(r.inputs.template_vertices, demo.template_surface.vertices.rows());

  // The result surface: the template's vertices and triangles, deformed, in millimetres.
  const sinew::offline::RegisteredShape& shape = *r.shape;
  ASSERT_EQ(shape.surface.vertices.rows(), demo.template_surface.vertices.rows());
  EXPECT_TRUE((shape.surface.triangles.array() == demo.template_surface.triangles.array()).all());

  // Against the known truth (not a trivial case: the template is far from it).
  const auto before =
      sinew::offline::vertex_to_surface_distances(demo.template_surface, demo.truth_surface);
  EXPECT_GT(before.max, 10.0);
  const sinew::offline::TruthDistances t =
      sinew::offline::truth_distances(shape.surface, demo.truth_surface);
  const double worst = std::max(t.result_to_truth.max, t.truth_to_result.max);
  EXPECT_LT(summary.marker_error_max * diagonal, 0.005 * diagonal);
  EXPECT_LT(t.result_to_truth.mean, 0.005 * diagonal);
  EXPECT_LT(t.truth_to_result.mean, 0.005 * diagonal);
  EXPECT_LT(worst, 0.03 * diagonal);
  EXPECT_LT(worst, 0.25 * before.max);
  EXPECT_GT(t.symmetric_mean_area_sampled, 0.0);
  EXPECT_LT(t.symmetric_mean_area_sampled, 0.005 * diagonal);

  // Vertex by vertex (the demo's material points are known): near the truth's.
  const double vertex_error =
      (shape.surface.vertices - demo.truth_surface.vertices).rowwise().norm().maxCoeff();
  EXPECT_LT(vertex_error, 0.05 * diagonal);

  // The report's figures: final marker errors, tet quality, coverage, plastic field.
  ASSERT_EQ(shape.marker_errors.size(), static_cast<std::size_t>(demo.markers.rows()));
  EXPECT_LT(*std::max_element(shape.marker_errors.begin(), shape.marker_errors.end()),
            0.005 * diagonal);
  EXPECT_EQ(shape.result_quality.inverted_tets, 0);
  EXPECT_GT(shape.template_quality.min_dihedral_degrees, 5.0);
  EXPECT_GT(shape.result_quality.min_dihedral_degrees, 5.0);
  EXPECT_NE(shape.result_quality.min_dihedral_degrees, shape.template_quality.min_dihedral_degrees);
  EXPECT_EQ(shape.Fp.rows(), r.problem.tets.rows());
  EXPECT_EQ(shape.det_Fp.size(), r.problem.tets.rows());
  EXPECT_GT(shape.det_Fp.maxCoeff(), 1.05);  // the free part was stretched
  EXPECT_GT(shape.coverage.nominal_spacing, 0.0);
  EXPECT_FALSE(r.landmark_errors.has_value());  // the demo has no landmarks
}

TEST(RegisterCase, TooFewMarkersForAFreeObjectIsAnInputError) {
  sinew::offline::RegistrationCase c = demo_case_in("register_case_free").c;
  c.attachments = {};
  c.icp_markers = c.icp_markers.topRows(2).eval();
  int prepared = 0;
  sinew::offline::RegisterCaseHooks hooks;
  hooks.prepared = [&](const sinew::offline::PreparedCase&) { ++prepared; };
  try {
    sinew::offline::register_case(c, {}, hooks);
    FAIL() << "no error";
  } catch (const sinew::offline::RegistrationInputError& e) {
    EXPECT_NE(std::string(e.what()).find("free object"), std::string::npos) << e.what();
  }
  EXPECT_EQ(prepared, 0);  // stopped before any work
}

// The ICP weight ramp a case gets when it gives none (default_icp_weight_ramp): from 1e-7 of
// alpha when landmarks hold the object's extremities through the ICP stage, from 1e-3 otherwise;
// a ramp the case gives is kept. Read from the prepared problem, before any solve.
TEST(RegisterCase, DefaultRampStartsLowerWhenLandmarksHoldTheExtremities) {
  const DemoCaseFiles files = demo_case_in("register_case_ramp");
  const sinew::tools::DemoCase& demo = files.demo;
  struct Stop {};
  auto ramp_of = [](const sinew::offline::RegistrationCase& c) {
    std::vector<double> ramp;
    sinew::offline::RegisterCaseHooks hooks;
    hooks.prepared = [&](const sinew::offline::PreparedCase& p) {
      ramp = p.options.icp_weight_ramp;
      throw Stop{};
    };
    EXPECT_THROW(sinew::offline::register_case(c, {}, hooks), Stop);
    return ramp;
  };
  sinew::offline::RegistrationCase c = files.c;
  c.landmarks = {};
  const std::vector<double> without = ramp_of(c);
  ASSERT_EQ(without.size(), 9u);
  EXPECT_DOUBLE_EQ(without.front(), 1e-3);
  EXPECT_DOUBLE_EQ(without.back(), 1e-1);

  // Two landmarks: two template vertices, held where they are.
  c.landmarks.template_points = demo.template_surface.vertices.topRows(2);
  c.landmarks.target_points = demo.template_surface.vertices.topRows(2);
  const std::vector<double> with = ramp_of(c);
  ASSERT_EQ(with.size(), 21u);
  EXPECT_DOUBLE_EQ(with.front(), 1e-7);
  EXPECT_DOUBLE_EQ(with[3], 1e-6);
  EXPECT_DOUBLE_EQ(with.back(), 1e-1);

  // Landmarks left out of the ICP stage hold nothing there: the short ramp.
  c.weights.icp_stage_landmarks = false;
  EXPECT_EQ(ramp_of(c).size(), 9u);

  // A ramp the case gives is the ramp.
  c.weights.icp_stage_landmarks = true;
  c.weights.icp_weight_ramp = std::vector<double>{0.5};
  EXPECT_EQ(ramp_of(c), std::vector<double>{0.5});
}

}  // namespace
