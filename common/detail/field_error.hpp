#pragma once
/// The one-line message of an invalid option field, shared by every options struct's validate()
/// (rt and offline): "<prefix><name> = <value> <constraint>", e.g.
/// "EquilibriumOptions::max_iterations = 0 must be >= 1".

#include <sstream>
#include <string>
#include <string_view>

namespace sinew::common::detail {

template <class T>
std::string field_error(std::string_view prefix, std::string_view name, const T& value,
                        std::string_view constraint) {
  std::ostringstream s;
  s << prefix << name << " = " << value << " " << constraint;
  return s.str();
}

}  // namespace sinew::common::detail
