// sinew-synth end to end: run the real binary on small sequences and check the files, the truth
// against beam theory (independent of the project's solver), the rendered pixels against the truth
// (also through the camera's homography), determinism, and one-line errors with exit status 2.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <set>
#include <vector>

#include "tests/support/run_tool.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using sinew::testing::read_text;
using sinew::testing::run_tool;
using sinew::testing::scratch_dir;

const std::string kTool = std::string(SINEW_BINARY_DIR) + "/tools/sinew-synth";
constexpr double kPi = 3.14159265358979323846;

struct Sequence {
  fs::path dir;
  sinew::testing::ToolResult result;
  json init;
  std::vector<json> truth;  // one object per line of truth.jsonl

  cv::Mat frame(int k) const {
    char name[32];
    std::snprintf(name, sizeof name, "f_%04d.png", k);
    return cv::imread((dir / "frames" / name).string(), cv::IMREAD_UNCHANGED);
  }
};

Sequence synth(const std::string& name, const std::string& args) {
  Sequence s;
  // CTest runs every test case in its own process, in parallel: keep their folders apart.
  const std::string test = ::testing::UnitTest::GetInstance()->current_test_info()->name();
  s.dir = scratch_dir("sinew_synth_" + name + "_" + test);
  s.result = run_tool(kTool + " --out " + (s.dir / "out").string() + " " + args, s.dir);
  s.dir /= "out";
  if (s.result.exit_status != 0) return s;
  s.init = json::parse(read_text(s.dir / "init.json"));
  std::ifstream in(s.dir / "truth.jsonl");
  for (std::string line; std::getline(in, line);) s.truth.push_back(json::parse(line));
  return s;
}

std::vector<std::string> frame_files(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir / "frames"))
    names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

struct Point {
  double x, y;
};
Point node_xy(const json& nodes, int i) {
  return {nodes[i][0].get<double>(), nodes[i][1].get<double>()};
}

/// Unit normal of the polyline at node i (central difference of the neighbours).
Point normal_at(const json& nodes, int i) {
  const int a = std::max(0, i - 1), b = std::min(static_cast<int>(nodes.size()) - 1, i + 1);
  const Point pa = node_xy(nodes, a), pb = node_xy(nodes, b);
  const double dx = pb.x - pa.x, dy = pb.y - pa.y, l = std::hypot(dx, dy);
  return {-dy / l, dx / l};
}

/// Mean grey level of the (2r + 1)² pixels around the pixel nearest to p.
double mean_around(const cv::Mat& image, Point p, int r = 1) {
  const int cx = static_cast<int>(std::lround(p.x)), cy = static_cast<int>(std::lround(p.y));
  double sum = 0.0;
  int count = 0;
  for (int y = cy - r; y <= cy + r; ++y) {
    for (int x = cx - r; x <= cx + r; ++x) {
      sum += image.at<unsigned char>(std::clamp(y, 0, image.rows - 1),
                                     std::clamp(x, 0, image.cols - 1));
      ++count;
    }
  }
  return sum / count;
}

double stddev_around(const cv::Mat& image, Point p, int r) {
  const cv::Rect box(static_cast<int>(std::lround(p.x)) - r, static_cast<int>(std::lround(p.y)) - r,
                     2 * r + 1, 2 * r + 1);
  cv::Scalar mean, sd;
  cv::meanStdDev(image(box & cv::Rect(0, 0, image.cols, image.rows)), mean, sd);
  return sd[0];
}

Point apply_homography(const json& h, Point p) {
  auto H = [&](int r, int c) { return h[3 * r + c].get<double>(); };
  const double w = H(2, 0) * p.x + H(2, 1) * p.y + H(2, 2);
  return {(H(0, 0) * p.x + H(0, 1) * p.y + H(0, 2)) / w,
          (H(1, 0) * p.x + H(1, 1) * p.y + H(1, 2)) / w};
}

// A short noise-free cantilever at a small load (λ = 0.1 on the last frame), with an occluder on
// frames 2–3 and the beam gone on frame 4. Run once, checked by several tests.
const Sequence& small_cantilever() {
  static const Sequence s =
      synth("small",
            "--scenario cantilever --frames 6 --width 320 --height 240 --lambda-max 0.1 "
            "--noise 0 --clutter 0 --occluder 2:2 --vanish 4:1");
  return s;
}

TEST(SinewSynth, WritesFramesTruthAndInitWithTheDocumentedSchema) {
  const Sequence& s = small_cantilever();
  ASSERT_EQ(s.result.exit_status, 0) << s.result.err;
  EXPECT_EQ(frame_files(s.dir),
            (std::vector<std::string>{"f_0000.png", "f_0001.png", "f_0002.png", "f_0003.png",
                                      "f_0004.png", "f_0005.png"}));
  const cv::Mat f0 = s.frame(0);
  ASSERT_FALSE(f0.empty());
  EXPECT_EQ(f0.type(), CV_8UC1);
  EXPECT_EQ(f0.cols, 320);
  EXPECT_EQ(f0.rows, 240);
  EXPECT_NE(s.result.out.find("truth.jsonl"), std::string::npos) << s.result.out;
  EXPECT_NE(s.result.out.find("init.json"), std::string::npos) << s.result.out;

  // init.json: exactly the tracker's schema.
  std::set<std::string> keys;
  for (const auto& item : s.init.items()) keys.insert(item.key());
  EXPECT_EQ(keys, (std::set<std::string>{"nodes", "fixed", "material", "observation",
                                         "half_width_px", "load_nodes"}));
  ASSERT_EQ(s.init["nodes"].size(), 17u) << "16 tracker elements by default";
  for (const auto& node : s.init["nodes"]) EXPECT_EQ(node.size(), 2u);
  EXPECT_EQ(s.init["fixed"], json::parse(R"([{"node": 0, "dofs": ["ux", "uy", "theta"]}])"));
  EXPECT_EQ(s.init["load_nodes"], json::parse("[16]"));
  EXPECT_EQ(s.init["observation"], "edge");
  EXPECT_EQ(s.init["half_width_px"].get<double>(), 6.0);
  const json& m = s.init["material"];
  EXPECT_DOUBLE_EQ(m["E"].get<double>(), 1000.0);
  EXPECT_DOUBLE_EQ(m["G"].get<double>(), 1000.0 / 2.6);
  EXPECT_DOUBLE_EQ(m["A"].get<double>(), 12.0);
  EXPECT_DOUBLE_EQ(m["I"].get<double>(), 12.0 * 12.0 * 12.0 / 12.0);

  // truth.jsonl: one line per frame, the documented keys, frame 0 = the init nodes with θ = 0.
  ASSERT_EQ(s.truth.size(), 6u);
  for (int k = 0; k < 6; ++k) {
    const json& t = s.truth[k];
    std::set<std::string> tk;
    for (const auto& item : t.items()) tk.insert(item.key());
    EXPECT_EQ(tk, (std::set<std::string>{"frame", "nodes", "loads", "lambda", "occluded", "visible",
                                         "homography"}));
    EXPECT_EQ(t["frame"].get<int>(), k);
    ASSERT_EQ(t["nodes"].size(), 17u);
    ASSERT_EQ(t["loads"].size(), 17u);
    EXPECT_EQ(t["nodes"][0].size(), 3u);
    EXPECT_EQ(t["occluded"].get<bool>(), k == 2 || k == 3) << k;
    EXPECT_EQ(t["visible"].get<bool>(), k != 4) << k;
    ASSERT_EQ(t["homography"].size(), 9u);
    for (int i = 0; i < 9; ++i) EXPECT_EQ(t["homography"][i].get<double>(), i % 4 == 0 ? 1.0 : 0.0);
  }
  for (int i = 0; i < 17; ++i) {
    EXPECT_NEAR(s.truth[0]["nodes"][i][0].get<double>(), s.init["nodes"][i][0].get<double>(), 1e-9);
    EXPECT_NEAR(s.truth[0]["nodes"][i][1].get<double>(), s.init["nodes"][i][1].get<double>(), 1e-9);
    EXPECT_EQ(s.truth[0]["nodes"][i][2].get<double>(), 0.0);
  }
}

TEST(SinewSynth, CantileverLoadsRampAndSmallLoadDeflectionMatchesLinearTheory) {
  const Sequence& s = small_cantilever();
  ASSERT_EQ(s.result.exit_status, 0) << s.result.err;
  ASSERT_EQ(s.truth.size(), 6u);
  const json& nodes = s.init["nodes"];
  const Point base = node_xy(nodes, 0), tip = node_xy(nodes, 16);
  const double L = std::hypot(tip.x - base.x, tip.y - base.y);
  EXPECT_NEAR(L, 0.6 * 320, 1e-6);
  const Point axis{(tip.x - base.x) / L, (tip.y - base.y) / L};
  const Point normal{-axis.y, axis.x};
  EXPECT_GT(normal.y, 0.9) << "bends towards the image's +y";
  const double EI = s.init["material"]["E"].get<double>() * s.init["material"]["I"].get<double>();

  for (int k = 0; k < 6; ++k) {
    const json& t = s.truth[k];
    const double lambda = t["lambda"].get<double>();
    EXPECT_NEAR(lambda, 0.1 * k / 5.0, 1e-12) << "linear ramp, frame " << k;
    const double P = lambda * EI / (L * L);
    const json& f = t["loads"][16];
    EXPECT_NEAR(f[0].get<double>(), P * normal.x, 1e-9 * EI / (L * L)) << k;
    EXPECT_NEAR(f[1].get<double>(), P * normal.y, 1e-9 * EI / (L * L)) << k;
    EXPECT_EQ(f[2].get<double>(), 0.0);
    for (int i = 0; i < 16; ++i) {
      for (int j = 0; j < 3; ++j) EXPECT_EQ(t["loads"][i][j].get<double>(), 0.0) << k << " " << i;
    }
    // The clamp does not move.
    EXPECT_NEAR(t["nodes"][0][0].get<double>(), base.x, 1e-9);
    EXPECT_NEAR(t["nodes"][0][1].get<double>(), base.y, 1e-9);
    EXPECT_EQ(t["nodes"][0][2].get<double>(), 0.0);
  }
  // Euler–Bernoulli: v = P L³/(3EI) = λ L/3, tip rotation P L²/(2EI) = λ/2 (shear adds 0.3%).
  const json& last = s.truth[5];
  const Point moved = node_xy(last["nodes"], 16);
  const double v = (moved.x - tip.x) * normal.x + (moved.y - tip.y) * normal.y;
  const double lambda = last["lambda"].get<double>();
  ASSERT_GT(v, 1.0) << "the comparison needs a visible deflection";
  EXPECT_NEAR(v, lambda * L / 3.0, 0.02 * lambda * L / 3.0);
  EXPECT_NEAR(last["nodes"][16][2].get<double>(), lambda / 2.0, 0.02 * lambda / 2.0);
}

TEST(SinewSynth, CantileverAtLambda3MatchesTheElastica) {
  // Large deflection reached through the warm-started ramp 0, 1, 2, 3: the exact elastica gives
  // (L − x)/L = 0.254420, v/L = 0.603253, θ = 0.986017 at the tip.
  const Sequence s = synth("elastica",
                           "--scenario cantilever --frames 4 --width 320 --height 240 "
                           "--lambda-max 3 --noise 0 --clutter 0");
  ASSERT_EQ(s.result.exit_status, 0) << s.result.err;
  const Point base = node_xy(s.init["nodes"], 0), tip0 = node_xy(s.init["nodes"], 16);
  const double L = std::hypot(tip0.x - base.x, tip0.y - base.y);
  const Point axis{(tip0.x - base.x) / L, (tip0.y - base.y) / L}, normal{-axis.y, axis.x};
  const Point tip = node_xy(s.truth[3]["nodes"], 16);
  const Point d{tip.x - base.x, tip.y - base.y};
  EXPECT_NEAR(1.0 - (d.x * axis.x + d.y * axis.y) / L, 0.254420, 2e-3);
  EXPECT_NEAR((d.x * normal.x + d.y * normal.y) / L, 0.603253, 2e-3);
  EXPECT_NEAR(s.truth[3]["nodes"][16][2].get<double>(), 0.986017, 2e-3);
}

TEST(SinewSynth, RenderedBeamIsDarkOnTheTrueCentrelineAndBrightBesideIt) {
  const Sequence& s = small_cantilever();
  ASSERT_EQ(s.result.exit_status, 0) << s.result.err;
  const double w = s.init["half_width_px"].get<double>();
  for (int k : {0, 5}) {
    SCOPED_TRACE("frame " + std::to_string(k));
    const cv::Mat image = s.frame(k);
    ASSERT_FALSE(image.empty());
    const json& nodes = s.truth[k]["nodes"];
    for (int i = 1; i < 16; i += 2) {
      const Point p = node_xy(nodes, i), n = normal_at(nodes, i);
      EXPECT_LT(mean_around(image, p), 100.0) << "node " << i;
      EXPECT_GT(mean_around(image, {p.x + 3 * w * n.x, p.y + 3 * w * n.y}), 150.0) << "node " << i;
      EXPECT_GT(mean_around(image, {p.x - 3 * w * n.x, p.y - 3 * w * n.y}), 150.0) << "node " << i;
    }
  }
  // Frame 4: the beam vanished; frames 2 and 3: a textured occluder over the middle fifth only.
  const cv::Mat gone = s.frame(4);
  for (int i = 2; i < 16; i += 4)
    EXPECT_GT(mean_around(gone, node_xy(s.truth[4]["nodes"], i)), 150.0);
  const cv::Mat occluded = s.frame(2);
  const json& nodes = s.truth[2]["nodes"];
  EXPECT_GT(mean_around(occluded, node_xy(nodes, 8)), 75.0);
  EXPECT_GT(stddev_around(occluded, node_xy(nodes, 8), 3), 3.0) << "textured, not a flat beam";
  EXPECT_LT(stddev_around(s.frame(1), node_xy(s.truth[1]["nodes"], 8), 3), 1.0);
  for (int i : {2, 4, 12, 14}) EXPECT_LT(mean_around(occluded, node_xy(nodes, i)), 100.0) << i;
}

TEST(SinewSynth, CameraMotionHomographyMapsTruthIntoTheFrame) {
  const Sequence s = synth("camera",
                           "--scenario cantilever --frames 4 --width 320 --height 240 "
                           "--lambda-max 0.5 --noise 0 --clutter 0 --camera-motion pan_rotate");
  ASSERT_EQ(s.result.exit_status, 0) << s.result.err;
  const json& h = s.truth[3]["homography"];
  double off_identity = 0.0;
  for (int i = 0; i < 9; ++i) {
    off_identity = std::max(off_identity, std::abs(h[i].get<double>() - (i % 4 == 0 ? 1.0 : 0.0)));
  }
  EXPECT_GT(off_identity, 0.01) << "the camera moved";
  EXPECT_EQ(h[8].get<double>(), 1.0);
  const cv::Mat image = s.frame(3);
  const json& nodes = s.truth[3]["nodes"];
  const double w = s.init["half_width_px"].get<double>();
  int dark_at_unmapped = 0;
  for (int i = 1; i < 16; i += 2) {
    const Point p = node_xy(nodes, i), n = normal_at(nodes, i);
    EXPECT_LT(mean_around(image, apply_homography(h, p)), 100.0) << "node " << i;
    EXPECT_GT(mean_around(image, apply_homography(h, {p.x + 3 * w * n.x, p.y + 3 * w * n.y})),
              150.0);
    dark_at_unmapped += mean_around(image, p) < 100.0;
  }
  EXPECT_LT(dark_at_unmapped, 8) << "the check above must depend on the homography";
}

TEST(SinewSynth, FreeCurvedBeamHasUnequalElementsAndSelfEquilibratedLoads) {
  const Sequence s = synth("free",
                           "--scenario free_curved --frames 5 --width 320 --height 240 "
                           "--thickness thin --noise 0 --clutter 0");
  ASSERT_EQ(s.result.exit_status, 0) << s.result.err;
  EXPECT_EQ(s.init["fixed"], json::array());
  EXPECT_FALSE(s.init.contains("load_nodes"));
  EXPECT_EQ(s.init["observation"], "dark_line");
  EXPECT_EQ(s.init["half_width_px"].get<double>(), 1.25);
  EXPECT_DOUBLE_EQ(s.init["material"]["A"].get<double>(), 2.5);
  const json& ref = s.init["nodes"];
  ASSERT_EQ(ref.size(), 17u);
  double shortest = 1e300, longest = 0.0, L = 0.0;
  for (int i = 0; i < 16; ++i) {
    const Point a = node_xy(ref, i), b = node_xy(ref, i + 1);
    const double l = std::hypot(b.x - a.x, b.y - a.y);
    shortest = std::min(shortest, l);
    longest = std::max(longest, l);
    L += l;
  }
  EXPECT_GT(longest / shortest, 1.6);
  EXPECT_LT(longest / shortest, 2.5);
  // Curved: the first and last elements differ in direction by tens of degrees.
  const Point n0 = normal_at(ref, 0), n16 = normal_at(ref, 16);
  EXPECT_LT(n0.x * n16.x + n0.y * n16.y, std::cos(30.0 * kPi / 180.0));

  const double EI = 1000.0 * s.init["material"]["I"].get<double>();
  double largest_force = 0.0;
  for (int k = 0; k < 5; ++k) {
    SCOPED_TRACE("frame " + std::to_string(k));
    const json& t = s.truth[k];
    EXPECT_NEAR(t["lambda"].get<double>(), 5.0 * std::sin(0.75 * kPi * k / 4.0), 1e-12);
    double fx = 0, fy = 0, moment = 0, fmax = 0;
    for (int i = 0; i < 17; ++i) {
      const Point p = node_xy(t["nodes"], i);
      const double a = t["loads"][i][0].get<double>(), b = t["loads"][i][1].get<double>();
      fx += a;
      fy += b;
      moment += p.x * b - p.y * a + t["loads"][i][2].get<double>();
      fmax = std::max(fmax, std::hypot(a, b));
    }
    largest_force = std::max(largest_force, fmax);
    const double scale = EI / (L * L);
    EXPECT_NEAR(fx, 0.0, 1e-9 * scale);
    EXPECT_NEAR(fy, 0.0, 1e-9 * scale);
    EXPECT_NEAR(moment, 0.0, 1e-8 * scale * L) << "balanced in the deformed, moved state";
    // Thin dark line on the true centreline.
    const cv::Mat image = s.frame(k);
    for (int i = 1; i < 16; i += 3) {
      const Point p = node_xy(t["nodes"], i), n = normal_at(t["nodes"], i);
      EXPECT_LT(mean_around(image, p, 0), 100.0) << "node " << i;
      EXPECT_GT(mean_around(image, {p.x + 4 * n.x, p.y + 4 * n.y}, 0), 150.0) << "node " << i;
    }
  }
  EXPECT_GT(largest_force, 1.0 * EI / (L * L)) << "the beam is loaded";
  EXPECT_GT(std::abs(s.truth[4]["nodes"][0][2].get<double>()), 1e-3) << "rigid rotation in theta";
}

TEST(SinewSynth, SameArgumentsGiveIdenticalBytes) {
  const std::string args =
      "--scenario cantilever --frames 3 --width 320 --height 240 --lambda-max 1 --noise 8 "
      "--clutter 12 --occluder 1:1 --camera-motion pan_rotate --seed 7";
  const Sequence a = synth("same_a", args), b = synth("same_b", args);
  ASSERT_EQ(a.result.exit_status, 0) << a.result.err;
  ASSERT_EQ(b.result.exit_status, 0) << b.result.err;
  for (const std::string file : {"init.json", "truth.jsonl", "frames/f_0000.png",
                                 "frames/f_0001.png", "frames/f_0002.png"}) {
    const std::string bytes = read_text(a.dir / file);
    EXPECT_FALSE(bytes.empty()) << file;
    EXPECT_TRUE(bytes == read_text(b.dir / file)) << file;
  }
  // Another seed changes the noise and clutter.
  const Sequence c = synth("same_c",
                           "--scenario cantilever --frames 3 --width 320 --height 240 "
                           "--lambda-max 1 --noise 8 --clutter 12 --occluder 1:1 "
                           "--camera-motion pan_rotate --seed 8");
  ASSERT_EQ(c.result.exit_status, 0) << c.result.err;
  EXPECT_FALSE(read_text(a.dir / "frames/f_0000.png") == read_text(c.dir / "frames/f_0000.png"));
}

// The whisker pad's pole presses the whisker without friction: on every contact frame the
// contact point lies on the pole's surface (its radius plus the whisker's half width there,
// 0.5·(3 − 2s/L) px), the force is normal to the deflected whisker there (a frictionless pole
// cannot push along it; the line from the pole's centre through the contact node, used before,
// was up to 7° off the normal: a component along the whisker of up to 12 % of the force, which a
// tracker's normal contact force was then scored against), pushing it away from the pole, and no
// part of the whisker lies inside the pole. With the pole sliding along the whisker, the contact
// point moves along it.
TEST(SinewSynth, WhiskerPadContactIsFrictionlessOnThePoleAndSlidesWithIt) {
  const auto dir = scratch_dir("sinew_synth_pad_contact");
  const auto r = run_tool(kTool + " --scenario whisker-pad --whiskers 1 --pole-travel 0.2 " +
                              "--frames 120 --out " + (dir / "out").string(),
                          dir);
  ASSERT_EQ(r.exit_status, 0) << r.err;
  std::ifstream in(dir / "out" / "truth.jsonl");
  int contacts = 0;
  double arc_min = 1e9, arc_max = 0.0, deepest = 0.0;
  for (std::string line; std::getline(in, line);) {
    const json t = json::parse(line);
    const json& w = t["whiskers"][0];
    if (w["contact"].is_null()) continue;
    ++contacts;
    const json& c = w["contact"];
    const json& x = w["centreline"];
    const double px = c["point"][0], py = c["point"][1];
    const double cx = t["pole"]["centre"][0], cy = t["pole"]["centre"][1];
    const double radius = t["pole"]["radius"], s = c["arc_length_px"], length = w["length_px"];
    auto reach = [&](double arc) { return radius + 0.5 * (3.0 - 2.0 * arc / length); };
    const double dx = px - cx, dy = py - cy, d = std::hypot(dx, dy);
    EXPECT_NEAR(d, reach(s), 1e-3) << "frame " << t["frame"];
    // The contact node's index along the centreline (its nodes are equally spaced in arc length).
    const int fine = static_cast<int>(x.size()) - 1;
    const int k = static_cast<int>(std::lround(s / length * fine));
    ASSERT_TRUE(k >= 1 && k < fine) << "frame " << t["frame"];
    const double tx = double(x[k + 1][0]) - double(x[k - 1][0]);
    const double ty = double(x[k + 1][1]) - double(x[k - 1][1]);
    const double fx = c["force"][0], fy = c["force"][1], f = std::hypot(fx, fy);
    ASSERT_GT(f, 0.0);
    EXPECT_NEAR((fx * tx + fy * ty) / (f * std::hypot(tx, ty)), 0.0, 1e-9)
        << "frame " << t["frame"];
    EXPECT_GT(fx * dx + fy * dy, 0.0) << "frame " << t["frame"] << ": the pole pushes";
    for (int i = 0; i <= fine; ++i) {
      const double di = std::hypot(double(x[i][0]) - cx, double(x[i][1]) - cy);
      deepest = std::min(deepest, di - reach(length * i / fine));
    }
    arc_min = std::min(arc_min, s);
    arc_max = std::max(arc_max, s);
  }
  EXPECT_GT(contacts, 20);
  EXPECT_GT(arc_max - arc_min, 20.0) << "the contact point moves along the whisker";
  EXPECT_GT(deepest, -0.05) << "px: a node of the whisker inside the pole";
}

TEST(SinewSynth, BadArgumentsGiveOneLineNamingTheOptionAndExit2) {
  const std::string small = " --frames 6 --width 320 --height 240";
  struct Case {
    std::string name, args, expected;
  };
  const std::vector<Case> cases = {
      {"scenario", "--scenario banana" + small, "--scenario"},
      {"frames", "--scenario cantilever --frames 1 --width 320 --height 240", "--frames"},
      {"frames_text", "--scenario cantilever --frames many", "--frames"},
      {"thickness", "--scenario cantilever --thickness medium" + small, "--thickness"},
      {"camera", "--scenario cantilever --camera-motion zoom" + small, "--camera-motion"},
      {"occluder_form", "--scenario cantilever --occluder 3" + small, "--occluder"},
      {"occluder_range", "--scenario cantilever --occluder 5:10" + small, "--occluder"},
      {"occluder_count", "--scenario cantilever --occluder 2:0" + small, "--occluder"},
      {"vanish_form", "--scenario cantilever --vanish a:b" + small, "--vanish"},
      {"lambda", "--scenario cantilever --lambda-max -1" + small, "--lambda-max"},
      {"does_not_fit", "--scenario cantilever --lambda-max 50" + small, "--width/--height"},
      {"pole_travel", "--scenario whisker-pad --pole-travel 0.5" + small, "--pole-travel"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const auto dir = scratch_dir("sinew_synth_bad_" + c.name);
    const auto r = run_tool(kTool + " --out " + (dir / "out").string() + " " + c.args, dir);
    EXPECT_EQ(r.exit_status, 2) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find(c.expected), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir / "out")) << "nothing written";
  }
}

TEST(SinewSynth, UnwritableOrMissingOutGivesOneLineAndExit2) {
  const std::string small = " --frames 6 --width 320 --height 240";
  // Unwritable --out: a path below a regular file.
  const auto dir = scratch_dir("sinew_synth_bad_out");
  sinew::testing::write_text(dir / "blocker", "a file, not a folder");
  const auto r = run_tool(
      kTool + " --scenario cantilever" + small + " --out " + (dir / "blocker" / "out").string(),
      dir);
  EXPECT_EQ(r.exit_status, 2) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_NE(r.err.find("--out"), std::string::npos) << r.err;
  // Missing --out.
  const auto missing = run_tool(kTool + " --scenario cantilever", dir);
  EXPECT_EQ(missing.exit_status, 2) << missing.err;
  EXPECT_EQ(std::count(missing.err.begin(), missing.err.end(), '\n'), 1) << missing.err;
  EXPECT_NE(missing.err.find("--out"), std::string::npos) << missing.err;
}

}  // namespace
