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

}  // namespace sinew::offline
