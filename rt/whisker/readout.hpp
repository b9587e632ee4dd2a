#pragma once
/// What a whisker lab reads out per whisker and frame, from a tracked beam state: the base angle,
/// the curvature over an arc-length window from the follicle and its change from rest (Δκ), and
/// the reaction at the follicle: the moment M0 and the axial and lateral forces that hold the
/// tracked shape.
///
/// The moment is the beam's constitutive law M = E·I·Δκ, exact at large deflections (it is the
/// force from Δκ that small-deflection formulas approximate), read from the first elements'
/// curvature changes and extrapolated to the follicle (WhiskerReadoutOptions::moment_elements).
/// The force is the load the follicle applies on the whisker: its first node belongs to the first
/// element only, so it is that element's internal force there, p = ∂U/∂u (seed 000, eq. 6;
/// common/beam/beam_element.hpp). The rest shape is the tracker's reference (the shape the whisker
/// was detected or initialised with) until set_rest().
///
/// Units: with an image scale (WhiskerPhysics::mm_per_px > 0) the whisker is a tapered cone of
/// circular section, E·I(s) = E·π·r(s)⁴/4 with r linear from the base to the tip radius over the
/// whisker's length, and forces are reported in newtons, moments in newton-metres, curvatures in
/// 1/mm. Without one, in the tracker's own pixel model (its section, lengths in pixels).
///
/// Sign conventions (image coordinates, x right, y down): angles and moments are positive from +x
/// towards +y; the axial force is along the base tangent pointing out of the follicle, the lateral
/// force along that tangent turned by +90°.
///
/// Set-up allocates; evaluate() does not.

#include <Eigen/Core>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/beam/beam_element.hpp"
#include "rt/tracker.hpp"

namespace sinew::rt {

/// The whisker's material, taper and the image scale.
struct WhiskerPhysics {
  /// Image scale, millimetres per pixel; 0: report in the tracker's pixel model units.
  double mm_per_px = 0.0;
  /// Young's modulus, GPa, > 0. Default: rat vibrissae, 3.34 ± 1.48 GPa in tensile tests of 22
  /// whiskers (Quist, Faruqi and Hartmann 2011, J. Biomech. 44:2775). Set your animal's.
  double young_modulus_gpa = 3.34;
  /// Poisson's ratio for the shear stiffness G = E / (2 (1 + ν)), in (−1, 0.5).
  double poisson_ratio = 0.3;
  /// Radius at the follicle and at the tip, micrometres (base > 0, 0 ≤ tip ≤ base): needed with a
  /// scale; they differ between whiskers and animals by factors, so there is no default.
  double base_radius_um = 0.0;
  double tip_radius_um = 0.0;
  /// Full length of the whisker (the taper's), mm; 0: the tracked length here (WhiskerSession
  /// measures each whisker's instead: rt/whisker/taper_length.hpp).
  double length_mm = 0.0;

  bool si() const { return mm_per_px > 0.0; }
  /// The tapered cone's section at arc length s_mm from the follicle of a whisker of length
  /// length_mm (the taper's: length_mm above if set): EA and GA in newtons (shear correction 0.9
  /// of a solid circle), EI in N·m².
  common::BeamSection section_at(double s_mm, double whisker_length_mm) const;
  std::optional<std::string> validate() const;
};

/// A named whisker's material and taper from the literature (the image scale stays 0: it is the
/// camera's, not the whisker's); std::nullopt for a name it does not know. Known:
/// - "rat-c2": the rat's C2 whisker. Length 33.6 mm and base radius 69.5 µm (diameter 139 µm):
///   the means of the C2 whiskers in the per-whisker table pooled from seven studies by Belli,
///   Yang, Bresee and Hartmann 2017 (J. Neurophysiol. 117:1807, supplemental table 1); tip radius
///   1.6 µm: the mean of that table's C2 whiskers with a measured tip; Young's modulus 3.34 GPa:
///   tensile tests of 22 rat vibrissae (Quist, Faruqi and Hartmann 2011, J. Biomech. 44:2775;
///   ±1.48 GPa between whiskers). Individual whiskers differ from these means by ~10 % in radius
///   (so ~40 % in E·I): measure your animal's where the forces matter.
/// - "mouse-c2": the mouse's C2 whisker. Length 13.2 mm: measured in 3D on 16 C2 whiskers of 8
///   mice (13.2 ± 1.5 mm; Bresee, Belli, Luo and Hartmann 2023, J. Exp. Biol. 226:jeb245597);
///   base radius 33.5 µm: the default of the Svoboda/O'Connor labs' whisker-analysis package
///   (a code default, no paper table; other lab scripts use 30 and 36.5 µm); tip radius 1.5 µm:
///   the Hires, Pammer, Svoboda and Golomb 2013 model (eLife 2:e01350); Young's modulus
///   3.34 GPa BORROWED FROM THE RAT (the rat-c2 value above): no tensile test of mouse whiskers
///   is published. The radius is the least firm value, and E·I goes with its fourth power:
///   measure your animal's where the forces matter.
std::optional<WhiskerPhysics> whisker_preset(std::string_view name);
/// The names whisker_preset() knows, for help texts and error messages.
const std::vector<std::string>& whisker_preset_names();

struct WhiskerReadoutOptions {
  WhiskerPhysics physics;
  /// Direction of the head's axis in the image, degrees from +x towards +y: base angles are
  /// measured from it.
  double axis_angle_deg = 0.0;
  /// The arc-length window from the follicle over which the curvature is the mean turn of the
  /// tangent, pixels, 0 ≤ from < to (clamped to the whisker's length).
  double curvature_from_px = 0.0;
  double curvature_to_px = 30.0;
  /// M0 is the moment M = E·I·Δκ of the first this many elements (at their midpoints)
  /// extrapolated to the follicle by a least-squares line, ≥ 1 (1: the first element's). Between
  /// the follicle and a contact the moment is linear in arc length, so the line is exact there and
  /// averages the tracking noise of single elements' curvatures.
  int moment_elements = 3;

  std::optional<std::string> validate() const;
};

/// Per whisker and frame.
struct WhiskerReadout {
  double base_angle_deg = 0.0;   ///< tangent at the follicle against the head axis
  double curvature = 0.0;        ///< mean over the window, 1/mm (SI) or 1/px
  double delta_curvature = 0.0;  ///< curvature minus the rest shape's over the same window
  /// M0, the moment the follicle applies on the whisker, N·m (SI) or model units: −E·I·Δκ
  /// extrapolated to the follicle (see WhiskerReadoutOptions::moment_elements).
  double moment = 0.0;
  /// The force at the follicle, N (SI) or model units. From the first element's axial and shear
  /// strains, which tracking noise dominates (the fit stretches a whisker by fractions of a
  /// pixel): not yet a measurement. The contact load fit will give it.
  double force_axial = 0.0;
  double force_lateral = 0.0;
  /// The first element's load p at the follicle: its moment (the same quantity as `moment`, from
  /// one element's curvature and shear: noisier).
  double moment_first_element = 0.0;
  Eigen::Vector2d force = Eigen::Vector2d::Zero();  ///< the same force in image axes
};

/// The read-out of one tracked whisker (a beam tracked by rt::Tracker, first node the follicle).
class WhiskerReadoutModel {
 public:
  /// model: the tracker's beam (its rest shape and sections). Check valid().
  WhiskerReadoutModel(const common::BeamModel& model, WhiskerReadoutOptions options);

  bool valid() const { return error_.empty(); }
  const std::string& error() const { return error_; }
  const WhiskerReadoutOptions& options() const { return options_; }
  /// The rest shape's curvature over the window (1/mm or 1/px).
  double rest_curvature() const { return rest_curvature_; }
  /// First element's section in the reported units (E·A, G·A, E·I).
  const common::BeamSection& base_section() const { return section_; }

  /// The read-out at beam state u (3n: ux, uy in pixels, θ), e.g. Tracker::state(). No allocation.
  WhiskerReadout evaluate(const Eigen::Ref<const Eigen::VectorXd>& u) const noexcept;
  /// Takes the whisker at state u as unloaded (e.g. the first tracked frame, or a frame without
  /// contact): Δκ, the moment and the forces are then changes from that state. Until it is
  /// called, the tracker's reference shape (the detected or initial curve) is the rest shape.
  /// No allocation.
  void set_rest(const Eigen::Ref<const Eigen::VectorXd>& u) noexcept;

 private:
  // The first element's internal force p (6) at state u, in the reported units.
  common::Vector6d first_element_load(const Eigen::Ref<const Eigen::VectorXd>& u) const noexcept;

  WhiskerReadoutOptions options_;
  std::string error_;
  Eigen::Matrix2Xd rest_;                   // reference nodes, pixels
  Eigen::Matrix2Xd tangents_;               // unit reference tangents at the nodes
  Eigen::VectorXd arc_;                     // reference arc length at each node, pixels
  common::BeamElementReference reference_;  // first element, in the reported length unit
  common::BeamSection section_;             // first element, reported units
  double length_unit_ = 1.0;     // reported length unit per pixel (m per px with SI, else 1)
  double curvature_unit_ = 1.0;  // 1/px → reported curvature unit
  double from_px_ = 0.0, to_px_ = 0.0;
  double rest_curvature_ = 0.0;
  common::Vector6d rest_load_ = common::Vector6d::Zero();  // first element's load at rest
  // The elements M0 is extrapolated from: bending stiffness (reported units), midpoint arc length
  // (reported length unit), reference length (pixels), rest moment.
  Eigen::VectorXd bending_, midpoint_, length_px_, rest_moment_;
};

}  // namespace sinew::rt
