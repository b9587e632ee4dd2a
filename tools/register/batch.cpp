#include "tools/register/batch.hpp"

#include <fmt/core.h>

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>

#include "tools/batch/child_processes.hpp"
#include "tools/batch/manifest_paths.hpp"
#include "tools/io/json_file.hpp"

namespace sinew::tools {
namespace {

namespace fs = std::filesystem;

std::string describe(const ChildOutcome& o) {
  if (const std::string abnormal = describe_abnormal_end(o); !abnormal.empty()) return abnormal;
  switch (o.exit_status) {
    case 0:
      return "registered";
    case 1:
      return "registration failed (exit 1, see its report.json)";
    case 2:
      return "bad input (exit 2)";
    default:
      return fmt::format("failed (exit {})", o.exit_status);
  }
}

}  // namespace

BatchManifest read_batch_manifest(const std::string& path) {
  return parse_json_file(
      path, [&](const nlohmann::json& doc) { return parse_batch_manifest(doc, path); });
}

BatchManifest parse_batch_manifest(const nlohmann::json& doc, const std::string& path) {
  const JsonCursor root(doc, path);
  root.expect_keys({"cases"});
  const JsonCursor cases = root.at("cases");
  const std::size_t n = cases.array_size();
  if (n == 0) cases.fail("is empty");
  BatchManifest m;
  m.path = path;
  std::map<std::string, std::size_t> out_dirs;  // normalised folder → first case using it
  for (std::size_t i = 0; i < n; ++i) {
    const JsonCursor e = cases.at(i);
    if (!e.value().is_object()) e.fail("must be {\"case\": FILE, \"out\": FOLDER}");
    e.expect_keys({"case", "out", "truth"});
    BatchCase c;
    c.case_path = resolve_manifest_path(path, e.at("case"));
    c.out_dir = resolve_manifest_path(path, e.at("out"));
    if (e.has("truth")) c.truth_path = resolve_manifest_path(path, e.at("truth"));
    const std::string key = fs::weakly_canonical(fs::absolute(c.out_dir)).string();
    const auto [it, inserted] = out_dirs.emplace(key, i);
    if (!inserted) {
      e.at("out").fail("= \"" + e.at("out").string() + "\" is also the output folder of cases[" +
                       std::to_string(it->second) + "]");
    }
    m.cases.push_back(std::move(c));
  }
  return m;
}

std::optional<std::size_t> select_batch_task(const BatchManifest& manifest,
                                             std::optional<long> task, const char* slurm_task) {
  return select_array_task(manifest.cases.size(), manifest.path, "case", task, slurm_task);
}

int run_batch(const BatchManifest& manifest, std::optional<std::size_t> task,
              const BatchCaseRunner& run_case, bool quiet) {
  const std::size_t n = manifest.cases.size();
  std::vector<std::size_t> selected;
  if (task) {
    selected.push_back(*task);
  } else {
    for (std::size_t i = 0; i < n; ++i) selected.push_back(i);
  }
  // One case at a time: each one's output follows its header line.
  std::map<std::size_t, ChildOutcome> by_case;
  run_in_children(
      selected, 1, "sinew-register", [&](std::size_t i) { return run_case(manifest.cases[i]); },
      [&](std::size_t i) {
        if (quiet) return;
        const BatchCase& c = manifest.cases[i];
        fmt::print("== case {} of {} ({}): {} -> {}\n", i, n, manifest.path, c.case_path,
                   c.out_dir);
        std::fflush(stdout);
      },
      [&](std::size_t i, const ChildOutcome& o) { by_case[i] = o; });
  std::vector<ChildOutcome> outcomes;
  for (const std::size_t i : selected) outcomes.push_back(by_case[i]);

  std::size_t failed = 0;
  for (const ChildOutcome& o : outcomes) failed += !o.ok();
  if (!quiet) {
    fmt::print("batch {}: {} of {} case{} registered, {} failed\n", manifest.path,
               selected.size() - failed, selected.size(), selected.size() == 1 ? "" : "s", failed);
    for (std::size_t k = 0; k < selected.size(); ++k) {
      const BatchCase& c = manifest.cases[selected[k]];
      fmt::print("  [{}] {} ({:.1f} s): {} -> {}\n", selected[k], describe(outcomes[k]),
                 outcomes[k].seconds, c.case_path, c.out_dir);
    }
    std::fflush(stdout);
  }
  for (std::size_t k = 0; k < selected.size(); ++k) {
    const ChildOutcome& o = outcomes[k];
    if (o.ok()) continue;
    std::cerr << "sinew-register: " << manifest.path << ": case " << selected[k] << " ("
              << manifest.cases[selected[k]].case_path << "): " << describe(o) << "\n";
  }
  if (task) return outcomes.front().task_status();
  return failed == 0 ? 0 : 1;
}

}  // namespace sinew::tools
