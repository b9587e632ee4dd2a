// Proof of the real-time contract: after the first frame, Tracker::track() performs no heap
// allocation, over hundreds of frames that exercise every path: good frames, an occluded stretch,
// frames without the object (lost), frames that hit the iteration bounds (not converged), the
// force verification, the load-node fit and the snake baseline.
//
// Two independent guards: counters on malloc/calloc/realloc and on global operator new (OpenCV or
// glibc allocations would bypass operator new), and Eigen's EIGEN_RUNTIME_NO_MALLOC assertion (this
// test compiles the tracker's sources itself with that macro and with assertions on).
#include <gtest/gtest.h>

#include <cstdlib>

#include "common/beam/static_solver.hpp"
#include "rt/tracker.hpp"
#include "rt/whisker/readout.hpp"
#include "rt/whisker/whisker_tracker.hpp"
// The one translation unit of this executable that includes it: malloc and operator new hooks.
#include "tests/support/allocation_counter.hpp"
#include "tests/support/beam_render.hpp"
#include "tests/support/whisker_render.hpp"

namespace sinew::rt {
namespace {

using sinew::testing::GreyImage;

struct Frames {
  std::vector<GreyImage> bent;      // load levels 0..levels-1
  std::vector<GreyImage> occluded;  // same, with a block over the middle of the beam
  GreyImage empty{320, 240, 200};   // no object: lost
};

common::BeamDescription cantilever(int per) {
  const int n = 8 * per + 1;
  Eigen::Matrix2Xd X(2, n);
  for (int i = 0; i < n; ++i) X.col(i) << 60.0 + 200.0 * i / (n - 1), 60.0;
  auto d = common::BeamDescription::uniform(X, {1000.0, 1000.0 / 2.6, 6.0, 18.0});
  d.clamp(0);
  return d;
}

Frames render(int levels) {
  Frames frames;
  const common::BeamModel fine(cantilever(4));
  common::StaticBeamSolver solver(fine);
  Eigen::VectorXd u = Eigen::VectorXd::Zero(fine.num_dofs()), f = u, f_prev = u;
  std::mt19937 gen(3);
  for (int k = 0; k < levels; ++k) {
    f.setZero();
    f[fine.num_dofs() - 2] = 0.6 * k / (levels - 1);
    EXPECT_TRUE(solver.solve(f, u, &f_prev).converged());
    f_prev = f;
    GreyImage img(320, 240, 200);
    sinew::testing::draw_band(img, sinew::testing::centreline_points(fine, u, 8), 3.0, 60);
    GreyImage occ = img;
    for (int y = 40; y < 200; ++y) {
      for (int x = 130; x < 180; ++x) occ.pixels[y * 320 + x] = 120;
    }
    sinew::testing::add_noise(img, 6.0, gen);
    sinew::testing::add_noise(occ, 6.0, gen);
    frames.bent.push_back(std::move(img));
    frames.occluded.push_back(std::move(occ));
  }
  return frames;
}

// Frame k of the test sequence: ping-pong through the load levels, occluded for a stretch, and
// empty (object gone) for a few frames.
const GreyImage& frame(const Frames& f, int k) {
  const int levels = static_cast<int>(f.bent.size());
  const int period = 2 * (levels - 1);
  const int phase = k % period;
  const int level = phase < levels ? phase : period - phase;
  if (k % 97 >= 90) return f.empty;
  if (k % 61 >= 45) return f.occluded[level];
  return f.bent[level];
}

struct Counts {
  long mallocs = 0, news = 0;
  int ok = 0, lost = 0, not_converged = 0, verified = 0, fitted = 0, predicted = 0;
};

Counts run(Tracker& tracker, const Frames& frames, int count) {
  Counts c;
  tracker.track(frames.bent[0].view());  // the first frame may warm up lazily (none does today)
  Eigen::internal::set_is_malloc_allowed(false);
  sinew::testing::AllocationCounter counter;
  for (int k = 1; k < count; ++k) {
    const FrameSummary s = tracker.track(frame(frames, k).view());
    c.ok += s.status == FrameStatus::kOk;
    c.lost += s.status == FrameStatus::kLost;
    c.not_converged += s.status == FrameStatus::kNotConverged;
    c.verified += s.verified;
    c.fitted += s.loads_fitted;
    c.predicted += s.predicted;
  }
  counter.stop();
  Eigen::internal::set_is_malloc_allowed(true);
  c.mallocs = counter.mallocs();
  c.news = counter.news();
  return c;
}

TEST(NoAllocation, BeamTrackerWithVerificationAndLoadFit) {
  if (!sinew::testing::allocation_counting_available())
    GTEST_SKIP() << sinew::testing::kAllocationCountingUnavailable;
  const Frames frames = render(12);
  TrackerOptions options;
  options.observation = ObservationMode::kEdge;
  options.half_width_px = 3.0;
  Tracker tracker(cantilever(1), options, {8});
  ASSERT_TRUE(tracker.valid()) << tracker.error();
  const Counts c = run(tracker, frames, 400);
  EXPECT_EQ(c.mallocs, 0);
  EXPECT_EQ(c.news, 0);
  // The run must have exercised the paths it claims to.
  SCOPED_TRACE("ok " + std::to_string(c.ok) + " lost " + std::to_string(c.lost) +
               " not converged " + std::to_string(c.not_converged) + " verified " +
               std::to_string(c.verified) + " fitted " + std::to_string(c.fitted));
  EXPECT_GT(c.ok, 150);
  EXPECT_GT(c.lost, 10);
  EXPECT_GT(c.verified, 200);
  EXPECT_GT(c.fitted, 100);
}

// Without verification the last repetition is predicted on most frames (a block-tridiagonal solve
// on the kept factorisation): that path allocates nothing either.
TEST(NoAllocation, BeamTrackerWithoutVerification) {
  if (!sinew::testing::allocation_counting_available())
    GTEST_SKIP() << sinew::testing::kAllocationCountingUnavailable;
  const Frames frames = render(12);
  TrackerOptions options;
  options.observation = ObservationMode::kEdge;
  options.half_width_px = 3.0;
  options.verify_forces = false;
  Tracker tracker(cantilever(1), options);
  ASSERT_TRUE(tracker.valid()) << tracker.error();
  const Counts c = run(tracker, frames, 300);
  EXPECT_EQ(c.mallocs, 0);
  EXPECT_EQ(c.news, 0);
  EXPECT_GT(c.ok, 150);
  EXPECT_GT(c.predicted, 50) << "the predicted repetition must have run";
}

TEST(NoAllocation, NonConvergingFramesAndSnake) {
  if (!sinew::testing::allocation_counting_available())
    GTEST_SKIP() << sinew::testing::kAllocationCountingUnavailable;
  const Frames frames = render(12);
  TrackerOptions options;
  options.observation = ObservationMode::kEdge;
  options.half_width_px = 3.0;
  options.max_repetitions = 1;  // the bound is hit on moving frames: not converged
  options.max_newton_iterations = 1;
  Tracker bounded(cantilever(1), options);
  ASSERT_TRUE(bounded.valid());
  const Counts c = run(bounded, frames, 300);
  EXPECT_EQ(c.mallocs, 0);
  EXPECT_EQ(c.news, 0);
  EXPECT_GT(c.not_converged, 50);

  TrackerOptions snake_options;
  snake_options.observation = ObservationMode::kEdge;
  snake_options.half_width_px = 3.0;
  snake_options.model = TrackerModel::kSnake;
  Tracker snake(cantilever(1), snake_options);
  ASSERT_TRUE(snake.valid());
  const Counts s = run(snake, frames, 300);
  EXPECT_EQ(s.mallocs, 0);
  EXPECT_EQ(s.news, 0);
  EXPECT_GT(s.ok + s.not_converged, 100);
}

// Ten whiskers on a 640 x 480 frame, whisking, with frames where half of them are gone (lost,
// discarded fits): WhiskerTracker::track() allocates nothing either.
TEST(NoAllocation, TenWhiskers) {
  if (!sinew::testing::allocation_counting_available())
    GTEST_SKIP() << sinew::testing::kAllocationCountingUnavailable;
  const Eigen::Vector2d centre(-80.0, 240.0);
  const double radius = 220.0;
  auto whiskers_at = [&](double rotation) {
    std::vector<sinew::testing::SceneWhisker> ws;
    for (int k = 0; k < 10; ++k) {
      sinew::testing::SceneWhisker w;
      const double phi = -0.6 + 0.12 * k;
      w.follicle = centre + radius * Eigen::Vector2d(std::cos(phi), std::sin(phi));
      w.angle = phi + 0.2 + rotation;
      w.kappa = 1.0 / 500.0;
      w.length = 150.0 + 5.0 * k;
      w.contrast = 6.0 + k;
      ws.push_back(w);
    }
    return ws;
  };
  std::vector<GreyImage> frames;
  std::mt19937 gen(5);
  for (int f = 0; f < 25; ++f) {
    GreyImage img = sinew::testing::backlit_face(640, 480, centre, radius);
    const auto ws = whiskers_at(0.15 * std::sin(2.0 * M_PI * f / 25.0));
    for (std::size_t k = 0; k < ws.size(); ++k) {
      if (f < 20 || k % 2 == 0) sinew::testing::draw_whisker(img, ws[k]);  // 20..24: half gone
    }
    sinew::testing::add_noise(img, 4.0, gen);
    frames.push_back(std::move(img));
  }
  std::vector<std::vector<Eigen::Vector2d>> init;
  for (const auto& w : whiskers_at(0.0)) init.push_back(w.points());
  WhiskerTracker tracker(init);
  ASSERT_TRUE(tracker.valid()) << tracker.error();
  tracker.track(frames[0].view());
  // The read-out (angle, curvature, follicle reaction in SI units) of every whisker every frame.
  std::vector<WhiskerReadoutModel> readouts;
  WhiskerReadoutOptions ro;
  ro.physics.mm_per_px = 0.05;
  ro.physics.base_radius_um = 40.0;
  ro.physics.tip_radius_um = 2.0;
  for (int w = 0; w < tracker.num_whiskers(); ++w) {
    readouts.emplace_back(tracker.whisker(w).model(), ro);
    ASSERT_TRUE(readouts.back().valid()) << readouts.back().error();
  }
  Eigen::internal::set_is_malloc_allowed(false);
  sinew::testing::AllocationCounter counter;
  int ok = 0, lost = 0;
  double moments = 0.0;
  for (int k = 1; k < 300; ++k) {
    tracker.track(frames[k % 25].view());
    for (int w = 0; w < tracker.num_whiskers(); ++w) {
      ok += tracker.result(w).status == FrameStatus::kOk;
      lost += tracker.result(w).status == FrameStatus::kLost;
      moments += std::abs(readouts[w].evaluate(tracker.whisker(w).state()).moment);
    }
  }
  counter.stop();
  EXPECT_TRUE(std::isfinite(moments));
  Eigen::internal::set_is_malloc_allowed(true);
  EXPECT_EQ(counter.mallocs(), 0);
  EXPECT_EQ(counter.news(), 0);
  SCOPED_TRACE("ok " + std::to_string(ok) + " lost " + std::to_string(lost));
  EXPECT_GT(ok, 2000);
  EXPECT_GT(lost, 50);
}

TEST(NoAllocation, CountersSeeAllocations) {
  // The guard itself must be able to fail.
  if (!sinew::testing::allocation_counting_available())
    GTEST_SKIP() << sinew::testing::kAllocationCountingUnavailable;
  sinew::testing::AllocationCounter counter;
  void* p = std::malloc(64);
  int* q = new int(3);
  counter.stop();
  std::free(p);
  delete q;
  EXPECT_EQ(counter.mallocs(), 1);
  EXPECT_EQ(counter.news(), 1);
}

}  // namespace
}  // namespace sinew::rt
