#pragma once
/// The stages of a registration (seed 003 §3.4, §4): the attachments alone, then the landmarks,
/// then the ICP markers, each stage a Gauss–Newton run on its own objective that starts where the
/// last one ended; a constant plastic strain fitted first gives the initial guess. A stage ends on
/// its iteration limit, a step η below min_step, a negligible relative decrease of Φ, a failed
/// line search or (ICP stage) every marker within max_marker_error (GaussNewtonOptions).
#include <Eigen/Core>
#include <vector>

#include "offline/constraints/constraints.hpp"
#include "offline/registration/gauss_newton_options.hpp"

namespace sinew::offline {

enum class RegistrationStage {
  kInitialFit,   ///< the constant-s initial guess
  kAttachments,  ///< attachments only
  kLandmarks,    ///< attachments + landmarks
  kIcpMarkers,   ///< attachments + ICP markers (landmarks off)
};
const char* to_string(RegistrationStage stage);

/// The inputs of a registration, in the tet mesh's frame (embedded material points).
struct RegistrationConstraints {
  /// Springs of f_net (kind kAttachment; weight = spring stiffness, N/m).
  std::vector<PointConstraint> attachments;
  /// Landmarks with correspondence (kind kLandmark; weight multiplies α).
  std::vector<PointConstraint> landmarks;
  /// ICP markers: world points to be met by the closest surface point (weight 1 each).
  std::vector<Eigen::Vector3d> icp_markers;
};

/// The stages a registration runs, in order (§4): the attachments (an attached object, not
/// `free`), the landmarks (unless they join the ICP stage: GaussNewtonOptions::
/// icp_stage_landmarks without landmark_stage), the ICP markers.
std::vector<RegistrationStage> registration_stages(const RegistrationConstraints& constraints,
                                                   const GaussNewtonOptions& options, bool free);

}  // namespace sinew::offline
