#include "tools/track/track_init.hpp"

#include <map>

#include "tools/io/beam_json.hpp"

namespace sinew::tools {

TrackInit read_track_init(const std::string& path) {
  return parse_json_file(path,
                         [&](const nlohmann::json& doc) { return parse_track_init(doc, path); });
}

TrackInit parse_track_init(const nlohmann::json& doc, const std::string& path) {
  const JsonCursor root(doc, path);
  root.expect_keys(
      {"nodes", "fixed", "material", "observation", "half_width_px", "load_nodes", "options"});
  TrackInit init;
  init.beam = parse_beam_description(root);
  const JsonCursor obs = root.at("observation");
  const std::string mode = obs.string();
  if (mode == "edge") {
    init.options.observation = rt::ObservationMode::kEdge;
  } else if (mode == "dark_line") {
    init.options.observation = rt::ObservationMode::kDarkLine;
  } else if (mode == "bright_line") {
    init.options.observation = rt::ObservationMode::kBrightLine;
  } else {
    obs.fail("= \"" + mode + "\" must be \"edge\", \"dark_line\" or \"bright_line\"");
  }
  if (root.has("half_width_px")) {
    init.options.half_width_px = root.at("half_width_px").positive_number();
  } else if (mode == "edge") {
    throw InputError(path + ": missing required field 'half_width_px' (edge mode)");
  }
  const int n = static_cast<int>(init.beam.rest_positions.cols());
  if (root.has("load_nodes")) {
    const JsonCursor ln = root.at("load_nodes");
    for (std::size_t k = 0; k < ln.array_size(); ++k) {
      const long node = ln.at(k).integer();
      if (node < 0 || node >= n) {
        ln.at(k).fail("= " + std::to_string(node) + " is out of range (the beam has " +
                      std::to_string(n) + " nodes)");
      }
      init.load_nodes.push_back(static_cast<int>(node));
    }
  }
  if (root.has("options")) {
    const JsonCursor o = root.at("options");
    auto& t = init.options;
    const std::map<std::string, double*> reals = {
        {"min_strength", &t.min_strength},
        {"image_stiffness", &t.image_stiffness},
        {"min_image_length_px", &t.min_image_length_px},
        {"bending_memory", &t.bending_memory},
        {"research_px", &t.research_px},
        {"min_relative_strength", &t.min_relative_strength},
        {"object_residual_px", &t.object_residual_px},
        {"convergence_px", &t.convergence_px},
        {"tukey_c", &t.tukey_c},
        {"min_sigma_px", &t.min_sigma_px},
        {"min_inlier_fraction", &t.min_inlier_fraction},
        {"start_clearance_px", &t.start_clearance_px},
        {"start_mean_surround_px", &t.start_mean_surround_px},
        {"snake_stretch_weight", &t.snake_stretch_weight},
        {"snake_bend_weight", &t.snake_bend_weight}};
    const std::map<std::string, int*> integers = {
        {"samples_per_element", &t.samples_per_element},
        {"search_range_px", &t.search_range_px},
        {"first_search_range_px", &t.first_search_range_px},
        {"max_candidates", &t.max_candidates},
        {"line_surround_px", &t.line_surround_px},
        {"band_px", &t.band_px},
        {"max_repetitions", &t.max_repetitions},
        {"max_newton_iterations", &t.max_newton_iterations},
        {"verify_load_steps", &t.verify_load_steps},
        {"max_load_fit_iterations", &t.max_load_fit_iterations}};
    std::vector<std::string> keys = {"predict",      "verify_forces", "polarity",
                                     "observe_ends", "fit_moments",   "coupled_load_fit"};
    for (const auto& kv : reals) keys.push_back(kv.first);
    for (const auto& kv : integers) keys.push_back(kv.first);
    o.expect_keys(keys);
    for (const auto& [key, field] : reals) {
      if (o.has(key)) *field = o.at(key).finite_number();
    }
    for (const auto& [key, field] : integers) {
      if (o.has(key)) *field = static_cast<int>(o.at(key).integer());
    }
    if (o.has("predict")) t.predict = o.at("predict").boolean();
    if (o.has("observe_ends")) t.observe_ends = o.at("observe_ends").boolean();
    if (o.has("fit_moments")) t.fit_moments = o.at("fit_moments").boolean();
    if (o.has("coupled_load_fit")) t.coupled_load_fit = o.at("coupled_load_fit").boolean();
    if (o.has("verify_forces")) t.verify_forces = o.at("verify_forces").boolean();
    if (o.has("polarity")) {
      const std::string p = o.at("polarity").string();
      if (p == "auto") {
        t.polarity = rt::EdgePolarity::kAuto;
      } else if (p == "any") {
        t.polarity = rt::EdgePolarity::kAny;
      } else if (p == "dark_object") {
        t.polarity = rt::EdgePolarity::kDarkObject;
      } else if (p == "bright_object") {
        t.polarity = rt::EdgePolarity::kBrightObject;
      } else {
        o.at("polarity").fail("must be \"auto\", \"any\", \"dark_object\" or \"bright_object\"");
      }
    }
  }
  if (auto err = init.options.validate()) throw InputError(path + ": " + *err);
  return init;
}

}  // namespace sinew::tools
