#include "offline/registration/registration_case.hpp"

#include <cmath>

namespace sinew::offline {

const char* to_string(LengthUnit unit) {
  switch (unit) {
    case LengthUnit::kMillimetre:
      return "mm";
    case LengthUnit::kMetre:
      return "m";
    case LengthUnit::kUnspecified:
      break;
  }
  return "";
}

TetMesherOptions registration_mesh_options() {
  TetMesherOptions o;
  o.cell_size_fraction = 0.08;
  o.tets_across_thickness = 4;
  return o;
}

std::vector<double> default_icp_weight_ramp(bool landmarks) {
  std::vector<double> ramp;
  for (int decade = landmarks ? 7 : 3; decade >= 1; --decade) {
    ramp.insert(ramp.end(), 3, std::pow(10.0, -decade));
  }
  return ramp;
}

}  // namespace sinew::offline
