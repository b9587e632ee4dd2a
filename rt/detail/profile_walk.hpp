#pragma once
/// The inner loop of sample_profile (rt/observation.hpp): bilinear samples along a search line in
/// 16.16 fixed point, averaged over the rows of the tangent band. Integer arithmetic throughout, so
/// the portable and the AVX2 kernels give bit-identical profiles; the AVX2 one (runtime-dispatched,
/// two gathers per 8 samples) is what makes a search cheap enough for 1000 fps cameras.

#include <cstdint>

#include "rt/image_view.hpp"

namespace sinew::rt::detail {

/// A profile walk: rows start at (x[r], y[r]) in 16.16 fixed point (+128 so that the 8-bit
/// weights round to the nearest 1/256 px) and step by (dx, dy) per sample. Every sample of every
/// row must have its 2x2 bilinear support inside the image with 2 more bytes to the right (the
/// AVX2 kernel reads 4 bytes per row of the support), and positions must stay below 2¹⁵ px.
struct ProfileWalk {
  static constexpr int kMaxRows = 21;
  std::int32_t x[kMaxRows];  // rows [0, rows) are set (no zeroing: a walk is built per line)
  std::int32_t y[kMaxRows];
  int rows = 1;
  std::int32_t dx = 0, dy = 0;
};

/// std::lround without the library call (|v| < 2³¹): round half away from zero.
inline double round_half_away(double v) {
  return static_cast<double>(static_cast<long long>(v + (v >= 0.0 ? 0.5 : -0.5)));
}

/// Whether this CPU can run the AVX2 kernel (checked once).
bool avx2_available();

/// Writes `count` samples of the walk, each the mean over its rows. use_avx2 is ignored where
/// avx2_available() is false.
void walk_profile(const ImageView& image, const ProfileWalk& walk, int count, float* profile,
                  bool use_avx2);

}  // namespace sinew::rt::detail
