#pragma once
/// The beam part of the tools' JSON inputs (sinew-simulate's beam.json, sinew-track's init.json):
///   "nodes":    [[x, y], ...]                          reference polyline, ≥ 2 nodes
///   "fixed":    [{"node": i, "dofs": ["ux", "uy", "theta"]}, ...]   absent or empty: free beam
///   "material": {"E": .., "G": .., "A": .., "I": ..}   consistent units, all > 0
/// and, for simulations, "loads": [{"node": i, "f": [fx, fy, m]}, ...].

#include <Eigen/Core>

#include "common/beam/beam_model.hpp"
#include "tools/io/json_file.hpp"

namespace sinew::tools {

/// Reads nodes, fixed and material from `root`. Throws InputError naming the offending field.
common::BeamDescription parse_beam_description(const JsonCursor& root);

/// Reads "loads" (optional: zero loads when absent) for a beam of num_nodes nodes: 3·num_nodes.
Eigen::VectorXd parse_beam_loads(const JsonCursor& root, int num_nodes);

/// [[x, y, θ], ...] of the current configuration: X + (ux, uy) and θ per node.
nlohmann::json beam_state_to_json(const common::BeamModel& model,
                                  const Eigen::Ref<const Eigen::VectorXd>& u);

}  // namespace sinew::tools
