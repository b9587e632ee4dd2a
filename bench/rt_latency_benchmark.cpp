// Per-frame latency of rt::Tracker on 1024x768 frames of a moving cantilever (edge mode, noise
// σ = 8), for beams of 8–128 elements: median and 99th percentile over the frames, with and without
// the per-frame extras (force verification, load fit). Frames are rendered before timing.
//   build/release/bench/bench_rt_latency --benchmark_counters_tabular=true
#include <benchmark/benchmark.h>

#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <vector>

#include "common/beam/static_solver.hpp"
#include "rt/tracker.hpp"
// Hooks malloc/new to count allocations in the tracked frames (this is the executable's only TU).
#include "tests/support/allocation_counter.hpp"

namespace {

using namespace sinew;

constexpr int kWidth = 1024, kHeight = 768, kFrames = 60;
constexpr double kLength = 600.0, kHalfWidth = 6.0;

common::BeamDescription cantilever(int elements) {
  Eigen::Matrix2Xd X(2, elements + 1);
  for (int i = 0; i <= elements; ++i) X.col(i) << 200.0 + kLength * i / elements, 220.0;
  const double h = 2 * kHalfWidth;
  auto d = common::BeamDescription::uniform(X, {1000.0, 1000.0 / 2.6, h, h * h * h / 12.0});
  d.clamp(0);
  return d;
}

// Frames of a cantilever whose tip load swings λ = 0 → 3 → 0 (a smooth, continuous motion), drawn
// from a fine static solution with OpenCV (anti-aliased band) plus Gaussian noise.
const std::vector<cv::Mat>& frames() {
  static const std::vector<cv::Mat> all = [] {
    std::vector<cv::Mat> out;
    const common::BeamModel fine(cantilever(128));
    common::StaticSolverOptions options;
    options.load_steps = 4;
    common::StaticBeamSolver solver(fine, options);
    Eigen::VectorXd u = Eigen::VectorXd::Zero(fine.num_dofs()), f = u, f_prev = u;
    const double EI = fine.description().sections[0].EI;
    cv::RNG rng(1);
    for (int k = 0; k < kFrames; ++k) {
      const double lambda = 3.0 * std::sin(3.14159265358979 * k / (kFrames - 1));
      f.setZero();
      f[fine.num_dofs() - 2] = lambda * EI / (kLength * kLength);
      solver.solve(f, u, &f_prev);
      f_prev = f;
      std::vector<cv::Point> pts;
      for (int i = 0; i < fine.num_nodes(); ++i) {
        const Eigen::Vector2d x = fine.rest_positions().col(i) + u.segment<2>(3 * i);
        pts.emplace_back(cvRound(x.x() * 16), cvRound(x.y() * 16));
      }
      cv::Mat img(kHeight, kWidth, CV_8UC1, cv::Scalar(200));
      cv::polylines(img, pts, false, cv::Scalar(60), int(2 * kHalfWidth), cv::LINE_AA, 4);
      cv::Mat noise(img.size(), CV_16SC1);
      rng.fill(noise, cv::RNG::NORMAL, 0, 8);
      cv::Mat noisy;
      img.convertTo(noisy, CV_16SC1);
      noisy += noise;
      noisy.convertTo(img, CV_8UC1);
      out.push_back(img);
    }
    return out;
  }();
  return all;
}

void track_sequence(benchmark::State& state, bool extras) {
  const int elements = static_cast<int>(state.range(0));
  rt::TrackerOptions options;
  options.observation = rt::ObservationMode::kEdge;
  options.half_width_px = kHalfWidth;
  options.verify_forces = extras;
  const auto& seq = frames();
  std::vector<double> micros;
  int lost = 0;
  long allocations = 0, counted_frames = 0;
  for (auto _ : state) {
    rt::Tracker tracker(cantilever(elements), options,
                        extras ? std::vector<int>{elements} : std::vector<int>{});
    bool first = true;
    for (const cv::Mat& m : seq) {
      const rt::ImageView view{m.ptr<std::uint8_t>(), m.cols, m.rows,
                               static_cast<std::ptrdiff_t>(m.step[0])};
      std::optional<sinew::testing::AllocationCounter> counter;
      if (!first) counter.emplace();  // frames after the first must not allocate
      const auto t0 = std::chrono::steady_clock::now();
      const rt::FrameSummary s = tracker.track(view);
      const auto t1 = std::chrono::steady_clock::now();
      if (counter) {
        counter->stop();
        allocations += counter->total();
        ++counted_frames;
      }
      first = false;
      micros.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
      lost += s.status == rt::FrameStatus::kLost;
    }
  }
  std::sort(micros.begin(), micros.end());
  state.counters["median_us"] = micros[micros.size() / 2];
  state.counters["p99_us"] = micros[std::min(micros.size() - 1, micros.size() * 99 / 100)];
  state.counters["lost"] = lost;
  if (sinew::testing::allocation_counting_available() && counted_frames > 0) {
    state.counters["allocs_per_frame"] = double(allocations) / double(counted_frames);
  }
  state.SetComplexityN(elements);
}

void BM_TrackFrame(benchmark::State& state) {
  track_sequence(state, false);
}
void BM_TrackFrameWithForces(benchmark::State& state) {
  track_sequence(state, true);
}

BENCHMARK(BM_TrackFrame)->RangeMultiplier(2)->Range(8, 128)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_TrackFrameWithForces)
    ->RangeMultiplier(2)
    ->Range(8, 128)
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
