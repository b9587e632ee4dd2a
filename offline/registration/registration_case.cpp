#include "offline/registration/registration_case.hpp"

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

}  // namespace sinew::offline
