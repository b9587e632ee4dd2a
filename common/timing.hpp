#pragma once
/// Wall time for progress reports and summaries.

#include <chrono>

namespace sinew::common {

/// Seconds of steady-clock time since `start`.
inline double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace sinew::common
