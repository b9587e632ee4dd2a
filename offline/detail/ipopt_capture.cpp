#include "offline/detail/ipopt_capture.hpp"

#include <cstdio>

namespace sinew::offline::detail {

std::optional<int> parse_derivative_test(const std::string& text) {
  const std::string key = "Derivative checker detected ";
  const std::size_t at = text.find(key);
  int errors = 0;
  if (at != std::string::npos && std::sscanf(text.c_str() + at + key.size(), "%d", &errors) == 1) {
    return errors;
  }
  if (text.find("No errors detected by derivative checker") != std::string::npos) return 0;
  int flagged = 0;
  for (std::size_t p = 0; p < text.size(); p = text.find('\n', p) + 1) {
    if (text[p] == '*') ++flagged;
    if (text.find('\n', p) == std::string::npos) break;
  }
  if (flagged > 0) return flagged;
  return std::nullopt;
}

}  // namespace sinew::offline::detail
