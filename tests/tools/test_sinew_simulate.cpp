// sinew-simulate end to end: a converged simulation checked against the elastica, and every kind of
// bad input giving one line naming the problem and exit status 2 (never a crash, never an output).
#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>

#include "tests/support/run_tool.hpp"

namespace {

using sinew::testing::run_tool;
using sinew::testing::scratch_dir;
using sinew::testing::write_text;

const std::string kTool = std::string(SINEW_BINARY_DIR) + "/tools/sinew-simulate";

nlohmann::json cantilever(double tip_load) {
  nlohmann::json beam;
  beam["nodes"] = nlohmann::json::array();
  for (int i = 0; i <= 20; ++i) beam["nodes"].push_back({i / 20.0, 0.0});
  beam["fixed"] = {{{"node", 0}, {"dofs", {"ux", "uy", "theta"}}}};
  beam["material"] = {{"E", 1e6}, {"G", 1e6}, {"A", 1.0}, {"I", 1e-6}};
  beam["loads"] = {{{"node", 20}, {"f", {0.0, tip_load, 0.0}}}};
  return beam;
}

struct Outcome {
  sinew::testing::ToolResult result;
  bool wrote_output;
};

Outcome simulate_text(const std::string& name, const std::string& text) {
  const auto dir = scratch_dir("sinew_simulate_" + name);
  write_text(dir / "beam.json", text);
  Outcome o;
  o.result = run_tool(
      kTool + " --beam " + (dir / "beam.json").string() + " --out " + (dir / "state.json").string(),
      dir);
  o.wrote_output = std::filesystem::exists(dir / "state.json");
  return o;
}

TEST(SinewSimulate, CantileverMatchesElastica) {
  const auto dir = scratch_dir("sinew_simulate_ok");
  write_text(dir / "beam.json", cantilever(3.0).dump());
  const auto r = run_tool(
      kTool + " --beam " + (dir / "beam.json").string() + " --out " + (dir / "state.json").string(),
      dir);
  ASSERT_EQ(r.exit_status, 0) << r.err;
  const auto state = nlohmann::json::parse(sinew::testing::read_text(dir / "state.json"));
  EXPECT_TRUE(state["converged"].get<bool>());
  EXPECT_GT(state["iterations"].get<int>(), 0);
  ASSERT_EQ(state["nodes"].size(), 21u);
  const auto tip = state["nodes"][20];
  // λ = 3: (L − x)/L = 0.254420, v/L = 0.603253, θ = 0.986017 (exact elastica).
  EXPECT_NEAR(tip[0].get<double>(), 1 - 0.254420, 2e-3);
  EXPECT_NEAR(tip[1].get<double>(), 0.603253, 2e-3);
  EXPECT_NEAR(tip[2].get<double>(), 0.986017, 2e-3);
}

struct BadCase {
  std::string name, text, expected;  // expected: a piece of the one-line message
};

TEST(SinewSimulate, BadInputGivesOneLineErrorAndNoOutput) {
  auto with = [](auto edit) {
    nlohmann::json b = cantilever(1.0);
    edit(b);
    return b.dump(1);
  };
  // JSON has no infinity literal, but 1e400 parses to one.
  auto infinite_coordinate = [&] {
    std::string text = with([](auto& b) { b["nodes"][3][1] = "INFINITE"; });
    text.replace(text.find("\"INFINITE\""), 10, "1e400");
    return text;
  };
  const std::vector<BadCase> cases = {
      {"missing_material", with([](auto& b) { b.erase("material"); }), "'material'"},
      {"missing_E", with([](auto& b) { b["material"].erase("E"); }), "material.E"},
      {"negative_I", with([](auto& b) { b["material"]["I"] = -1.0; }), "material.I"},
      {"nan_literal", "{\"nodes\": [[0, 0], [1, NaN]]}", ":1:"},
      {"infinite", infinite_coordinate(), "1e400"},
      {"string_coordinate", with([](auto& b) { b["nodes"][2][0] = "x"; }), "nodes[2][0]"},
      {"load_node_range", with([](auto& b) { b["loads"][0]["node"] = 21; }), "loads[0].node"},
      {"fixed_node_range", with([](auto& b) { b["fixed"][0]["node"] = -1; }), "fixed[0].node"},
      {"bad_dof", with([](auto& b) { b["fixed"][0]["dofs"][1] = "uz"; }), "fixed[0].dofs[1]"},
      {"no_fixed_dof", with([](auto& b) { b.erase("fixed"); }), "fixed"},
      {"pinned_only", with([](auto& b) {
         b["fixed"][0]["dofs"] = {"ux", "uy"};
       }),
       "rigid"},
      {"unknown_key", with([](auto& b) { b["lods"] = 1; }), "'lods'"},
      {"duplicate_node", with([](auto& b) { b["nodes"][4] = b["nodes"][3]; }), "element 3"},
      {"one_node", with([](auto& b) {
         b["nodes"] = {{0, 0}};
       }),
       "nodes"},
      {"bad_steps", with([](auto& b) { b["steps"] = 0; }), "steps"},
      {"truncated", "{\"nodes\": [[0, 0],\n [1, 0]", ":2:"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.name);
    const Outcome o = simulate_text(c.name, c.text);
    EXPECT_EQ(o.result.exit_status, 2) << o.result.err;
    EXPECT_FALSE(o.wrote_output);
    EXPECT_NE(o.result.err.find(c.expected), std::string::npos) << o.result.err;
    EXPECT_EQ(std::count(o.result.err.begin(), o.result.err.end(), '\n'), 1) << o.result.err;
    EXPECT_NE(o.result.err.find("beam.json"), std::string::npos) << "names the file";
  }
}

TEST(SinewSimulate, UnreadableFile) {
  const auto dir = scratch_dir("sinew_simulate_missing");
  const auto r = run_tool(
      kTool + " --beam " + (dir / "nope.json").string() + " --out " + (dir / "state.json").string(),
      dir);
  EXPECT_EQ(r.exit_status, 2);
  EXPECT_NE(r.err.find("cannot open"), std::string::npos) << r.err;
}

}  // namespace
