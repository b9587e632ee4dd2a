#pragma once
/// The case file of sinew-register (seed 003: register a template organ to sparse scan markers),
/// parsed into typed structs. Every error is an InputError whose what() is ONE line naming the file
/// and the line:column (JSON syntax), the field (JSON path) or the line of a marker file.
///
/// Schema (keys other than these are errors, to catch typos):
/// {
///   "template": "liver.obj",        // surface .obj/.off/.stl/.ply (closed; tet-meshed by CGAL) or
///                                   // tet mesh .mesh/.veg/.node/.ele; relative to the case file
///   "units": "mm",                  // optional: "mm" or "m"; labels the report and scales 3D
///                                   // Slicer files (.fcsv, .mrk.json: millimetres) to metres
///   "mesh": {                       // optional, surface templates only (offline/meshing)
///     "cell_size_fraction": 0.06,   // tet circumradius bound / bounding-box diagonal
///     "tets_across_thickness": 4,   // thin parts this many tets across (tool default 4; 0: off)
///     "thin_fraction_of_median": 0, // only parts under this x the median thickness (0: all)
///     "facet_distance_fraction": 0.002, "facet_angle_degrees": 25, "cell_radius_edge_ratio": 3,
///     "odt": true, "lloyd": false, "perturb": true, "exude": true, "sliver_bound_degrees": 12,
///     "protect_sharp_features": false, "random_seed": 0, "max_vertices": 2000000,
///     "optimisation_time_limit_seconds": 0  // caps sliver perturbation/exudation (0: none)
///   },
///   "attachments": PAIRS,           // optional: material points fixed to bone etc. (§3.3);
///                                   // none: a free object (§3.6), >= 3 landmarks/markers
///   "landmarks": PAIRS,             // optional: points with known correspondence
///   "icp_markers": POINTS,          // optional: scan points without correspondence (ICP)
///   "transfer": ["hires.obj"],      // optional: surfaces in the template's frame to carry along
///   "scan_image": {                 // optional: cross-section PNGs of the result over the scan
///     "image": "ct.nii.gz",         // NIfTI / INRIA, world coordinates in the case's units
///     "mask": "mask.nii.gz",        // optional: its outline drawn in green, distances reported
///     "label": 1, "slices": 6, "window": [-160, 240]   // optional
///   },
///   "weights": {                    // optional; in the normalised frame (see below)
///     "alpha": 1e5, "beta": 1e4 or 0 (see RegistrationWeights), "attachment_stiffness": 10
///   },
///   "stop": {                       // optional
///     "max_iterations": 20,         // Gauss–Newton iterations per stage
///     "max_marker_error": 0.5,      // stop the ICP stage when every marker is this close (case
///                                   // units); default 0.1% of the template's diagonal
///     "min_step": 0.01,             // stop a stage when the line search's η is below this
///     "no_progress_iterations": 3   // stop the ICP stage when Φ after 3 iterations in a row
///                                   // is no lower than before them (0: never)
///   }
/// }
/// PAIRS: [{"template": [x, y, z], "target": [x, y, z], "label": "..." (optional)}, ...], or a file
///   name (.json/.csv/.txt of point pairs, offline/io/point_list_io.hpp), or
///   {"template": FILE, "target": FILE}: two point lists (.csv, .json, .mrk.json, .fcsv) matched by
///   order.
/// POINTS: [[x, y, z], ...] or a point-list file (.csv, .txt, .json, .mrk.json, .fcsv).
///
/// Normalised frame: the tool translates the template's bounding-box centre to the origin and
/// scales its diagonal to 1, with a unit material (μ = 1, ν = 0.4). alpha weighs the squared marker
/// misfit (in diagonals²) against the dimensionless plastic-strain smoothness ½‖L s‖², beta the
/// attachment misfit; attachment_stiffness is the spring constant of each attachment in units of
/// μ·diagonal (appendix G: scaling the stiffness is equivalent to scaling the weights). The same
/// numbers therefore suit a liver in millimetres and a bar in metres.

#include <nlohmann/json.hpp>

#include <string>

#include "offline/registration/registration_case.hpp"

namespace sinew::tools {

// The structs the parser fills belong to the library (offline/registration/registration_case.hpp).
using offline::LengthUnit;
using offline::PointPairSet;
using offline::RegistrationCase;
using offline::RegistrationStop;
using offline::RegistrationWeights;
using offline::to_string;

/// Reads and validates a case file and every marker file it names (the template itself is read
/// by the caller). Throws InputError (tools/io/json_file.hpp) with a one-line message.
RegistrationCase read_registration_case(const std::string& path);

/// The same for a case already parsed (the Python module's dict): path names it in messages, and
/// relative file names in it are resolved against path's folder ("" or a bare name: the working
/// folder).
RegistrationCase parse_registration_case(const nlohmann::json& doc, const std::string& path);

/// True for the tet-mesh extensions .mesh, .veg, .node, .ele (case-insensitive).
bool is_tet_mesh_path(const std::string& path);

}  // namespace sinew::tools
