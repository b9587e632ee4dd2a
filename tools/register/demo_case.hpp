#pragma once
/// Registration cases with a known answer, built in code so that they exist on any machine:
/// `sinew-register --make-demo-case DIR` (scripts/demo) and the tool's end-to-end tests.
///
/// The shapes are closed triangle surfaces along +x with the attached end at x = 0; the truth is
/// an analytic, smooth deformation (AxialStretchBend) of the part beyond the attached end, so
/// every truth is reachable by a plastic field (Fp = the polar stretch of ∇φ, stress-free) and
/// the only question is whether the registration finds it from sparse markers.

#include <Eigen/Core>
#include <string>

#include "offline/io/surface_mesh_io.hpp"

namespace sinew::tools {

/// A closed box [0, size.x] × [0, size.y] × [0, size.z] with n cells per side, triangles
/// counter-clockwise seen from outside.
offline::io::SurfaceMesh box_surface(const Eigen::Vector3d& size, const Eigen::Vector3i& n);

/// A capsule along x: a cylinder of elliptic cross-section (semi-axes radius_y, radius_z) closed
/// by two half-ellipsoids of axial semi-axis cap_length, from x = 0 to x = length (both poles on
/// the x axis, y = z = 0). segments around, cap_rings rings per cap (pole excluded), body_sections
/// sections along the cylinder; triangles counter-clockwise seen from outside.
struct CapsuleShape {
  double length = 100.0;     ///< pole to pole, > 2·cap_length
  double radius_y = 18.0;    ///< > 0
  double radius_z = 12.0;    ///< > 0
  double cap_length = 15.0;  ///< axial semi-axis of each end cap, > 0
  int segments = 24;         ///< ≥ 3
  int cap_rings = 5;         ///< ≥ 1
  int body_sections = 12;    ///< ≥ 1
};
offline::io::SurfaceMesh capsule_surface(const CapsuleShape& shape);

/// The known deformation: identity for x ≤ attached_until; beyond it the axis is stretched and
/// bent in the x–y plane while cross-sections stay normal to it (they move rigidly with the
/// axis's frame). With t = (x − attached_until) / free_length ∈ [0, 1]:
///   arc length along the deformed axis σ(t) = free_length·(t + stretch·t²)
///     (local axial stretch 1 at the attached end, 1 + 2·stretch at t = 1),
///   axis angle θ(t) = bend_radians·t² (no kink at the attached end),
///   φ(x, y, z) = c(t) + y·(−sin θ, cos θ, 0) + z·(0, 0, 1),  c(t) = (attached_until, 0, 0) +
///     ∫₀ᵗ (cos θ, sin θ, 0) σ'(τ) dτ (composite Simpson, 64 intervals: exact when bend = 0).
/// C¹ across x = attached_until; points beyond t = 1 continue the same formulas.
struct AxialStretchBend {
  double attached_until = 0.0;  ///< x of the end of the identity region
  double free_length = 1.0;     ///< length over which t runs from 0 to 1, > 0
  double stretch = 0.0;         ///< see σ(t); > −0.5 keeps σ' > 0 on [0, 1]
  double bend_radians = 0.0;    ///< axis angle at t = 1
  Eigen::Vector3d operator()(const Eigen::Vector3d& p) const;
};

/// The demo case of scripts/demo: a capsule (organ-sized, millimetres) attached at its x = 0 cap,
/// whose free part is stretched and bent by a known AxialStretchBend; ICP markers sampled on the
/// deformed surface, attachments = template points near the attached pole held in place.
struct DemoCaseOptions {
  CapsuleShape shape;          ///< millimetres
  double stretch = 0.15;       ///< AxialStretchBend::stretch (free part 1.15× longer)
  double bend_radians = 0.35;  ///< AxialStretchBend::bend_radians (tip turns ~20°)
  int markers = 80;            ///< ICP markers, ≥ 1
  unsigned seed = 1;           ///< marker sampling (own generator: same on every platform)
  /// "mesh" of case.json: coarse (about 1,300 tets, meshed in a fraction of a second) so that
  /// the whole registration takes seconds; CGAL's default facet distance (0.002) refines the
  /// curved caps far more, and its sliver optimisation then took 49 s here.
  double cell_size_fraction = 0.06;
  double facet_distance_fraction = 0.004;
  int max_iterations = 10;  ///< "stop" of case.json: Gauss–Newton iterations per stage
};

struct DemoCase {
  offline::io::SurfaceMesh template_surface;  ///< the capsule, millimetres
  offline::io::SurfaceMesh truth_surface;     ///< φ of every template vertex, same triangles
  Eigen::MatrixXd attachment_points;          ///< #A by 3: template points held in place
  Eigen::MatrixXd markers;                    ///< #M by 3: points of the deformed surface
  AxialStretchBend deformation;
  double max_displacement = 0.0;  ///< largest |φ(v) − v| over the template vertices, mm
  DemoCaseOptions options;
};

DemoCase make_demo_case(const DemoCaseOptions& options = {});

/// Writes dir/template.obj, dir/truth_surface.obj, dir/markers.csv, dir/attachments.json and
/// dir/case.json (referencing the others by relative name; "units": "mm"); creates dir. Throws
/// InputError (tools/io/json_file.hpp) with one line when a file cannot be written.
void write_demo_case(const DemoCase& demo, const std::string& dir);

/// One line (no newline) saying what write_demo_case wrote into dir: the capsule, its
/// attachments, markers and known deformation.
std::string demo_case_summary(const DemoCase& demo, const std::string& dir);

}  // namespace sinew::tools
