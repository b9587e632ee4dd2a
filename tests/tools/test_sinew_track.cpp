// sinew-track's inputs and failure modes end to end: a folder of images, a printf pattern, a single
// image and a video all track; unreadable input, malformed or inconsistent init.json and a polyline
// outside the first frame give one line naming the problem, exit status 2 and no results file.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>
#include <sstream>

#include "tests/support/run_tool.hpp"

namespace {

namespace fs = std::filesystem;
using sinew::testing::read_text;
using sinew::testing::run_tool;
using sinew::testing::write_text;

const std::string kBin = std::string(SINEW_BINARY_DIR) + "/tools/";

// A short 320x240 sequence made once per test process (CTest runs tests in parallel processes).
fs::path sequence() {
  static const fs::path dir = [] {
    const std::string test = ::testing::UnitTest::GetInstance()->current_test_info()->name();
    const fs::path d = sinew::testing::scratch_dir("sinew_track_" + test);
    const auto r = run_tool(kBin +
                                "sinew-synth --scenario cantilever --frames 6 --width 320 "
                                "--height 240 --lambda-max 0.5 --noise 4 --clutter 2 --out " +
                                (d / "seq").string(),
                            d);
    EXPECT_EQ(r.exit_status, 0) << r.err;
    return d;
  }();
  return dir;
}

struct Track {
  sinew::testing::ToolResult result;
  std::vector<nlohmann::json> lines;
  bool wrote = false;
};

Track track(const std::string& input, const fs::path& init, const std::string& extra = "") {
  const fs::path dir = sequence();
  const fs::path out = dir / "results.jsonl";
  fs::remove(out);
  Track t;
  t.result = run_tool(kBin + "sinew-track --quiet --input " + input + " --init " + init.string() +
                          " --out " + out.string() + " " + extra,
                      dir);
  t.wrote = fs::exists(out);
  if (t.wrote) {
    std::istringstream in(read_text(out));
    for (std::string line; std::getline(in, line);) t.lines.push_back(nlohmann::json::parse(line));
  }
  return t;
}

TEST(SinewTrack, ReadsPatternFolderImageAndVideo) {
  const fs::path seq = sequence() / "seq";
  const fs::path init = seq / "init.json";
  const Track pattern = track((seq / "frames/f_%04d.png").string(), init);
  ASSERT_EQ(pattern.result.exit_status, 0) << pattern.result.err;
  ASSERT_EQ(pattern.lines.size(), 6u);
  for (const auto& l : pattern.lines) {
    EXPECT_EQ(l["status"], "ok");
    for (const char* key :
         {"frame", "nodes", "forces", "rms_px", "verify_px", "iterations", "latency_us"}) {
      EXPECT_TRUE(l.contains(key)) << key;
    }
  }
  const Track folder = track((seq / "frames").string(), init);
  ASSERT_EQ(folder.result.exit_status, 0) << folder.result.err;
  ASSERT_EQ(folder.lines.size(), 6u);
  EXPECT_EQ(folder.lines[4]["nodes"], pattern.lines[4]["nodes"]) << "same frames, same fit";
  const Track strided = track((seq / "frames").string(), init, "--stride 2");
  ASSERT_EQ(strided.result.exit_status, 0) << strided.result.err;
  ASSERT_EQ(strided.lines.size(), 3u);
  EXPECT_EQ(strided.lines[1]["frame"], 2);
  EXPECT_EQ(strided.lines[2]["status"], "ok");

  const Track image = track((seq / "frames/f_0000.png").string(), init);
  ASSERT_EQ(image.result.exit_status, 0) << image.result.err;
  EXPECT_EQ(image.lines.size(), 1u);

  // A video made from the frames (lossless enough codec not needed: MJPG is fine for tracking).
  const fs::path video = sequence() / "seq.avi";
  {
    cv::VideoWriter w(video.string(), cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 30,
                      cv::Size(320, 240), false);
    ASSERT_TRUE(w.isOpened());
    for (int k = 0; k < 6; ++k) {
      char name[32];
      std::snprintf(name, sizeof name, "frames/f_%04d.png", k);
      w.write(cv::imread((seq / name).string(), cv::IMREAD_GRAYSCALE));
    }
  }
  const Track vid = track(video.string(), init,
                          "--first 1 --count 4 --overlay " + (sequence() / "overlay").string());
  ASSERT_EQ(vid.result.exit_status, 0) << vid.result.err;
  ASSERT_EQ(vid.lines.size(), 4u);
  EXPECT_EQ(vid.lines[0]["frame"], 1);
  EXPECT_TRUE(fs::exists(sequence() / "overlay/overlay_00001.png"));
}

TEST(SinewTrack, BadInputGivesOneLineAndNoResults) {
  const fs::path seq = sequence() / "seq";
  const nlohmann::json good = nlohmann::json::parse(read_text(seq / "init.json"));
  auto init_with = [&](const std::string& name, auto edit) {
    nlohmann::json j = good;
    edit(j);
    const fs::path p = sequence() / (name + ".json");
    write_text(p, j.dump());
    return p;
  };
  const fs::path malformed = sequence() / "malformed.json";
  write_text(malformed, "{\"nodes\": [[1, 2],\n  [3 4]]}");
  struct Case {
    std::string name, input;
    fs::path init;
    std::string expected;
  };
  const std::string frames = (seq / "frames/f_%04d.png").string();
  const std::vector<Case> cases = {
      {"missing_video", (sequence() / "nope.mp4").string(), seq / "init.json", "no such file"},
      {"no_match", (sequence() / "x_%04d.png").string(), seq / "init.json", "no images"},
      {"malformed", frames, malformed, "malformed.json:2:"},
      {"outside", frames, init_with("outside", [](auto& j) { j["nodes"][3][0] = 5000.0; }),
       "nodes[3]"},
      {"observation", frames, init_with("observation", [](auto& j) { j["observation"] = "ridge"; }),
       "observation"},
      {"load_node", frames, init_with("load_node", [](auto& j) { j["load_nodes"] = {99}; }),
       "load_nodes[0]"},
      {"option", frames,
       init_with("option",
                 [](auto& j) {
                   j["options"] = {{"search_rang", 3}};
                 }),
       "search_rang"},
      {"option_value", frames,
       init_with("option_value",
                 [](auto& j) {
                   j["options"] = {{"samples_per_element", 0}};
                 }),
       "samples_per_element"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.name);
    const Track t = track(c.input, c.init);
    EXPECT_EQ(t.result.exit_status, 2);
    EXPECT_FALSE(t.wrote);
    EXPECT_NE(t.result.err.find(c.expected), std::string::npos) << t.result.err;
    EXPECT_EQ(std::count(t.result.err.begin(), t.result.err.end(), '\n'), 1) << t.result.err;
  }
}

// --whiskers --detection-picture: the first frame magnified 3x with every whisker found drawn in
// its colour, its follicle a dot. Rendered pad (8 whiskers, a pole, a lick port): the picture has
// the frame's size times 3, and at 3x each follicle the detection record names there is a coloured
// (not grey) pixel.
TEST(SinewTrack, WhiskerDetectionPictureMarksEveryFollicleFound) {
  const fs::path dir = sinew::testing::scratch_dir("sinew_track_detection_picture");
  auto r = run_tool(
      kBin + "sinew-synth --scenario whisker-pad --frames 2 --out " + (dir / "pad").string(), dir);
  ASSERT_EQ(r.exit_status, 0) << r.err;
  const fs::path picture = dir / "detection.png", out = dir / "results.jsonl";
  r = run_tool(kBin + "sinew-track --quiet --whiskers --face left --count 1 --input " +
                   (dir / "pad" / "frames" / "f_%04d.png").string() + " --out " + out.string() +
                   " --detection-picture " + picture.string(),
               dir);
  ASSERT_EQ(r.exit_status, 0) << r.err;
  std::istringstream in(read_text(out));
  std::string first;
  std::getline(in, first);
  const auto detection = nlohmann::json::parse(first)["detection"];
  const cv::Mat frame = cv::imread((dir / "pad" / "frames" / "f_0000.png").string());
  const cv::Mat img = cv::imread(picture.string());
  ASSERT_FALSE(img.empty());
  EXPECT_EQ(img.cols, 3 * frame.cols);
  EXPECT_EQ(img.rows, 3 * frame.rows);
  ASSERT_GE(detection["whiskers"].size(), 8u);
  for (const auto& w : detection["whiskers"]) {
    const int x = static_cast<int>(std::lround(3.0 * w["follicle"][0].get<double>()));
    const int y = static_cast<int>(std::lround(3.0 * w["follicle"][1].get<double>()));
    const cv::Vec3b c = img.at<cv::Vec3b>(y, x);
    const int spread = std::max({c[0], c[1], c[2]}) - std::min({c[0], c[1], c[2]});
    EXPECT_GT(spread, 100) << "whisker " << w["id"] << " at " << x << ", " << y;
  }
}

// --whisker-preset rat-c2 is the same as its four values given one by one, and a value given beside
// it overrides the preset's: a thinner base radius scales the follicle's moment by about the
// fourth power of the radii (E·I of a circle), the mouse's preset is its four values too, and an
// unknown name is refused.
TEST(SinewTrack, AWhiskerPresetIsItsValuesAndAGivenValueOverridesIt) {
  const fs::path dir = sinew::testing::scratch_dir("sinew_track_whisker_preset");
  auto r = run_tool(kBin + "sinew-synth --scenario whisker-pad --frames 8 --whiskers 4 --out " +
                        (dir / "pad").string(),
                    dir);
  ASSERT_EQ(r.exit_status, 0) << r.err;
  const auto moments = [&](const std::string& physics) {
    const fs::path out = dir / "results.jsonl";
    fs::remove(out);
    const auto t = run_tool(kBin + "sinew-track --quiet --whiskers --face left --rest-frame 0 " +
                                "--mm-per-px 0.05 --input " +
                                (dir / "pad" / "frames" / "f_%04d.png").string() + " --out " +
                                out.string() + " " + physics,
                            dir);
    EXPECT_EQ(t.exit_status, 0) << t.err;
    std::vector<double> m0;
    std::istringstream in(read_text(out));
    for (std::string line; std::getline(in, line);) {
      const auto j = nlohmann::json::parse(line);
      if (!j.contains("whiskers")) continue;
      for (const auto& w : j["whiskers"]) {
        if (w.contains("m0_N_m")) m0.push_back(w["m0_N_m"].get<double>());
      }
    }
    return m0;
  };
  const auto preset = moments("--whisker-preset rat-c2");
  const auto given = moments(
      "--young-modulus-gpa 3.34 --base-radius-um 69.5 --tip-radius-um 1.6 --whisker-length-mm "
      "33.6");
  const auto thinner = moments("--whisker-preset rat-c2 --base-radius-um 50");
  ASSERT_GE(preset.size(), 20u);
  ASSERT_EQ(preset, given);
  ASSERT_EQ(thinner.size(), preset.size());
  const double expected = std::pow(50.0 / 69.5, 4);
  int compared = 0;
  for (std::size_t i = 0; i < preset.size(); ++i) {
    if (std::abs(preset[i]) < 1e-12) continue;
    EXPECT_NEAR(thinner[i] / preset[i], expected, 0.05 * expected) << i;
    ++compared;
  }
  EXPECT_GE(compared, 10);
  // The mouse's preset, likewise its four values; its thinner whisker carries smaller moments.
  const auto mouse = moments("--whisker-preset mouse-c2");
  ASSERT_EQ(mouse, moments("--young-modulus-gpa 3.34 --base-radius-um 33.5 --tip-radius-um 1.5 "
                           "--whisker-length-mm 13.2"));
  ASSERT_EQ(mouse.size(), preset.size());
  double mouse_sum = 0.0, rat_sum = 0.0;
  for (std::size_t i = 0; i < preset.size(); ++i) {
    mouse_sum += std::abs(mouse[i]);
    rat_sum += std::abs(preset[i]);
  }
  EXPECT_LT(mouse_sum, 0.2 * rat_sum);
  r = run_tool(kBin + "sinew-track --quiet --whiskers --whisker-preset mouse-x --input " +
                   (dir / "pad" / "frames" / "f_%04d.png").string(),
               dir);
  EXPECT_EQ(r.exit_status, 2);
  EXPECT_NE((r.out + r.err).find("rat-c2"), std::string::npos) << r.out << r.err;
}

}  // namespace
