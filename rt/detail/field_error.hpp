#pragma once
/// The one-line message of an invalid option field, shared by the rt option structs' validate():
/// "<prefix><name> = <value> <constraint>".

#include <sstream>
#include <string>

namespace sinew::rt::detail {

inline std::string field_error(const char* prefix, const char* name, double value,
                               const char* constraint) {
  std::ostringstream s;
  s << prefix << name << " = " << value << " " << constraint;
  return s.str();
}

}  // namespace sinew::rt::detail
