#pragma once
/// sinew-track's init file (and the Python module's Tracker): the beam (tools/io/beam_json.hpp),
///   "observation": "edge" | "dark_line" | "bright_line", "half_width_px" (edge mode),
///   "load_nodes": [i, ...] (the nodes whose loads the load fit recovers),
///   "options": {any rt::TrackerOptions field by name}.
/// Errors throw InputError naming the file and the offending field.

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "common/beam/beam_model.hpp"
#include "rt/tracker.hpp"
#include "tools/io/json_file.hpp"

namespace sinew::tools {

struct TrackInit {
  common::BeamDescription beam;
  rt::TrackerOptions options;
  std::vector<int> load_nodes;
};

TrackInit read_track_init(const std::string& path);
/// The same from a parsed document; `path` names it in errors.
TrackInit parse_track_init(const nlohmann::json& doc, const std::string& path);

}  // namespace sinew::tools
