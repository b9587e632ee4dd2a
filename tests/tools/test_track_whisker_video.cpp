// sinew-track on the real high-speed whisker video (../shared/data/whiskers/test_video_10s.mp4):
// the thick dark stimulus pole in edge mode from the initial polyline in examples/, 300 frames,
// results and an overlay for every frame. The pole does not move in this clip, so the tracked tip
// must stay where it starts (a check that can fail: a tracker that slides or drifts along the pole
// does exactly that). Skips when ../shared is absent.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>

#include "tests/support/run_tool.hpp"

namespace {

TEST(TrackWhiskerVideo, StimulusPoleAllFramesWithOverlay) {
  const std::string video = std::string(SINEW_SHARED_DIR) + "/data/whiskers/test_video_10s.mp4";
  if (!std::filesystem::exists(video)) GTEST_SKIP() << video << " not found";
  const auto dir = sinew::testing::scratch_dir("whisker_video");
  const std::string init = std::string(SINEW_SOURCE_DIR) + "/examples/whisker_pole_init.json";
  const auto r = sinew::testing::run_tool(
      std::string(SINEW_BINARY_DIR) + "/tools/sinew-track --input " + video + " --init " + init +
          " --out " + (dir / "results.jsonl").string() + " --overlay " + (dir / "overlay").string(),
      dir);
  ASSERT_EQ(r.exit_status, 0) << r.err;
  std::istringstream lines(sinew::testing::read_text(dir / "results.jsonl"));
  std::string line;
  int frames = 0, ok = 0;
  Eigen::Vector2d first_tip = Eigen::Vector2d::Zero();
  double drift = 0.0, worst_rms = 0.0;
  while (std::getline(lines, line)) {
    const auto j = nlohmann::json::parse(line);
    const auto& tip = j["nodes"].back();
    const Eigen::Vector2d p(tip[0].get<double>(), tip[1].get<double>());
    if (frames == 0) first_tip = p;
    drift = std::max(drift, (p - first_tip).norm());
    worst_rms = std::max(worst_rms, j["rms_px"].get<double>());
    ok += j["status"] == "ok";
    ++frames;
  }
  std::size_t overlays = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir / "overlay"))
    overlays += e.is_regular_file();
  std::cout << frames << " frames, " << ok << " ok, tip drift " << drift << " px, worst image RMS "
            << worst_rms << " px\n";
  EXPECT_EQ(frames, 300);
  EXPECT_EQ(overlays, 300u);
  EXPECT_GE(ok, 290);
  EXPECT_LT(drift, 2.0);
  EXPECT_LT(worst_rms, 1.5);
}

}  // namespace
