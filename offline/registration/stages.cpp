#include "offline/registration/stages.hpp"

namespace sinew::offline {

const char* to_string(RegistrationStage stage) {
  switch (stage) {
    case RegistrationStage::kInitialFit:
      return "initial-fit";
    case RegistrationStage::kAttachments:
      return "attachments";
    case RegistrationStage::kLandmarks:
      return "landmarks";
    case RegistrationStage::kIcpMarkers:
      return "icp";
  }
  return "unknown";
}

std::vector<RegistrationStage> registration_stages(const RegistrationConstraints& constraints,
                                                   const GaussNewtonOptions& options, bool free) {
  std::vector<RegistrationStage> stages;
  if (!free) stages.push_back(RegistrationStage::kAttachments);
  if (!constraints.landmarks.empty() &&
      (options.landmark_stage || constraints.icp_markers.empty() || !options.icp_stage_landmarks))
    stages.push_back(RegistrationStage::kLandmarks);
  if (!constraints.icp_markers.empty()) stages.push_back(RegistrationStage::kIcpMarkers);
  return stages;
}

}  // namespace sinew::offline
