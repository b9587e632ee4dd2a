#include "rt/observation.hpp"

#include "rt/detail/profile_walk.hpp"

#include <cmath>
#include <cstdint>
#include <limits>

#ifdef __SSE2__
#include <emmintrin.h>
#endif

namespace sinew::rt {

void sample_profile(const ImageView& image, const Eigen::Vector2d& centre,
                    const Eigen::Vector2d& normal, int first, int count, int band_px,
                    float* profile) {
  const Eigen::Vector2d tangent(normal.y(), -normal.x());
  const int band = band_px;
  const int rows = 2 * band + 1;

  // When the whole sampled parallelogram lies inside the image (its corners do, with a margin for
  // the fixed-point rounding and the 4-byte reads of the AVX2 kernel), samples skip the bounds
  // checks.
  bool inside = rows <= detail::ProfileWalk::kMaxRows && image.width < 32768 &&
                image.height < 32768 && double(image.height) * double(image.stride) < 2e9;
  for (const double k : {double(first), double(first + count - 1)}) {
    for (const double b : {-double(band), double(band)}) {
      const Eigen::Vector2d c = centre + k * normal + b * tangent;
      inside = inside && c.x() >= 0.01 && c.y() >= 0.01 && c.x() <= image.width - 4.01 &&
               c.y() <= image.height - 1.01;
    }
  }
  if (inside) {
    // Fast path in 16.16 fixed point: each band row walks along the normal by integer additions,
    // and the bilinear weights are the top 8 bits of the fraction (positions rounded to 1/256 px,
    // far below the ~0.05 px the noise allows). Measured: about 3x cheaper per sample than the
    // float walk with its float-int conversions, and the integer sums are exact.
    constexpr double kOne = 65536.0;
    detail::ProfileWalk walk;
    walk.rows = rows;
    walk.dx = static_cast<std::int32_t>(detail::round_half_away(normal.x() * kOne));
    walk.dy = static_cast<std::int32_t>(detail::round_half_away(normal.y() * kOne));
    for (int r = 0; r < rows; ++r) {
      const Eigen::Vector2d start = centre + double(first) * normal + double(r - band) * tangent;
      // Positive coordinates: truncating v + 0.5 rounds to nearest. + 128: the 8-bit weights
      // round to the nearest 1/256 px instead of truncating.
      walk.x[r] = static_cast<std::int32_t>(start.x() * kOne + 0.5) + 128;
      walk.y[r] = static_cast<std::int32_t>(start.y() * kOne + 0.5) + 128;
    }
    detail::walk_profile(image, walk, count, profile, /*use_avx2=*/true);
    return;
  }
  const float missing = std::numeric_limits<float>::quiet_NaN();
  const float inv = 1.0f / float(rows);
  for (int k = 0; k < count; ++k) {
    const Eigen::Vector2d p = centre + double(first + k) * normal;
    float sum = 0.0f;
    int n = 0;
    for (int b = -band; b <= band; ++b) {
      float v;
      if (image.sample(p.x() + b * tangent.x(), p.y() + b * tangent.y(), &v)) {
        sum += v;
        ++n;
      }
    }
    profile[k] = n == rows ? sum * inv : missing;
  }
}

void prefetch_profile(const ImageView& image, const Eigen::Vector2d& centre,
                      const Eigen::Vector2d& normal, int first, int count) {
  const Eigen::Vector2d a = centre + double(first) * normal;
  const Eigen::Vector2d b = centre + double(first + count - 1) * normal;
  auto inside = [&](const Eigen::Vector2d& c) {
    return c.x() >= 0.0 && c.y() >= 0.0 && c.x() <= image.width - 2.0 &&
           c.y() <= image.height - 2.0 && image.width < 32768 && image.height < 32768;
  };
  if (!inside(a) || !inside(b)) return;  // lines at the border are rare: no prefetch
  constexpr double kOne = 65536.0;
  std::int32_t x = static_cast<std::int32_t>(a.x() * kOne);
  std::int32_t y = static_cast<std::int32_t>(a.y() * kOne);
  const std::int32_t dx = static_cast<std::int32_t>(detail::round_half_away(normal.x() * kOne));
  const std::int32_t dy = static_cast<std::int32_t>(detail::round_half_away(normal.y() * kOne));
  for (int k = 0; k < count; ++k, x += dx, y += dy) {
    __builtin_prefetch(image.data + std::ptrdiff_t(y >> 16) * image.stride + (x >> 16));
  }
}

int find_candidates(const float* profile, int origin, float shift, const ProfileSearch& search,
                    float* response, Candidate* out) {
  // Response at each offset: signed central difference for edges, centre-surround for lines.
  // Only |k| ≤ range + 1 is needed (the local-maximum test reads one neighbour).
  const int range = search.range_px;
  const int s = search.line_surround_px;
  const int begin = origin - range - 1, end = origin + range + 1;
  // The response loops below write `response` while reading `profile`; the two never overlap
  // (callers pass separate halves of a scratch buffer), and saying so lets them vectorise.
  const float* __restrict in = profile;
  float* __restrict out_response = response;
  // One branch-free loop per mode (vectorised by the compiler).
  if (search.mode == ObservationMode::kEdge) {
    const float sign = 0.5f * static_cast<float>(search.expected_sign);
    if (search.expected_sign == 0) {
      for (int k = begin; k <= end; ++k) out_response[k] = 0.5f * std::abs(in[k + 1] - in[k - 1]);
    } else {
      for (int k = begin; k <= end; ++k) out_response[k] = sign * (in[k + 1] - in[k - 1]);
    }
  } else if (search.mode == ObservationMode::kDarkRidge) {
    // Both sides must be brighter than the centre: the darker side bounds the depth, so an edge
    // (one side as dark as the centre) answers ~0; relative to the brighter side, so the same
    // whisker answers the same under a bright or a dim part of the backlight.
    const float min_background = search.min_background;
    int k = begin;
    if (search.ridge_mean_surround) {
      for (; k <= end; ++k) {
        const float left = in[k - s], right = in[k + s];
        const float centre_value = 0.25f * (in[k - 1] + 2.0f * in[k] + in[k + 1]);
        const float lo = left < right ? left : right, hi = left < right ? right : left;
        const float mean_depth = 0.5f * (left + right) - centre_value;
        const float bounded = std::min(mean_depth, 4.0f * (lo - centre_value));
        out_response[k] = hi >= min_background ? 100.0f * bounded / (hi > 1.0f ? hi : 1.0f) : 0.0f;
      }
    } else {
#ifdef __SSE2__
      // Four offsets at a time: SSE2 is part of x86-64, and min/max/compare/and give the same
      // floats as the scalar loop's comparisons (NaN included), so the two agree bit for bit.
      const __m128 quarter = _mm_set1_ps(0.25f), two = _mm_set1_ps(2.0f),
                   hundred = _mm_set1_ps(100.0f);
      const __m128 one = _mm_set1_ps(1.0f), background = _mm_set1_ps(min_background);
      for (; k + 3 <= end; k += 4) {
        const __m128 left = _mm_loadu_ps(in + k - s), right = _mm_loadu_ps(in + k + s);
        const __m128 centre_value = _mm_mul_ps(
            quarter,
            _mm_add_ps(_mm_add_ps(_mm_loadu_ps(in + k - 1), _mm_mul_ps(two, _mm_loadu_ps(in + k))),
                       _mm_loadu_ps(in + k + 1)));
        const __m128 lo = _mm_min_ps(left, right), hi = _mm_max_ps(right, left);
        const __m128 depth =
            _mm_div_ps(_mm_mul_ps(hundred, _mm_sub_ps(lo, centre_value)), _mm_max_ps(hi, one));
        _mm_storeu_ps(out_response + k, _mm_and_ps(_mm_cmpge_ps(hi, background), depth));
      }
#endif
      for (; k <= end; ++k) {
        const float left = in[k - s], right = in[k + s];
        const float centre_value = 0.25f * (in[k - 1] + 2.0f * in[k] + in[k + 1]);
        const float lo = left < right ? left : right, hi = left < right ? right : left;
        out_response[k] =
            hi >= min_background ? 100.0f * (lo - centre_value) / (hi > 1.0f ? hi : 1.0f) : 0.0f;
      }
    }
  } else {
    // > 0 at a dark line.
    const float sign = search.mode == ObservationMode::kDarkLine ? 1.0f : -1.0f;
    for (int k = begin; k <= end; ++k) {
      const float surround = 0.5f * (in[k - s] + in[k + s]);
      const float centre_value = 0.25f * (in[k - 1] + 2.0f * in[k] + in[k + 1]);
      out_response[k] = sign * (surround - centre_value);
    }
  }

  // Local maxima within ±range, strongest first (insertion into the short output list).
  const bool from_profile = search.mode == ObservationMode::kDarkRidge &&
                            search.ridge_position_from_profile && !search.ridge_mean_surround;
  int found = 0;
  // Whether offset k is a local maximum strong enough: most offsets are not (NaN is not either).
  auto is_peak = [&](int k) {
    const float r0 = response[k];
    return r0 >= search.min_strength && r0 >= response[k - 1] && r0 > response[k + 1];
  };
  auto take = [&](int k) {
    const float r0 = response[k];
    const float rm = response[k - 1], rp = response[k + 1];
    // The vertex of a parabola through the peak and its neighbours: of the response, or of the
    // profile's darkness (only the centre samples, not the sides' noise).
    float am = rm, a0 = r0, ap = rp;
    if (from_profile) {
      am = -(profile[k - 2] + 2.0f * profile[k - 1] + profile[k]);
      a0 = -(profile[k - 1] + 2.0f * profile[k] + profile[k + 1]);
      ap = -(profile[k] + 2.0f * profile[k + 1] + profile[k + 2]);
    }
    const float denom = am - 2.0f * a0 + ap;
    float delta = denom < 0.0f ? 0.5f * (am - ap) / denom : 0.0f;
    if (delta > 0.5f) delta = 0.5f;
    if (delta < -0.5f) delta = -0.5f;
    Candidate c{float(k - origin) + delta - shift, r0};
    int pos = found < search.max_candidates ? found : search.max_candidates;
    while (pos > 0 && out[pos - 1].strength < c.strength) {
      if (pos < search.max_candidates) out[pos] = out[pos - 1];
      --pos;
    }
    if (pos < search.max_candidates) {
      out[pos] = c;
      if (found < search.max_candidates) ++found;
    }
  };
  int k = origin - range;
#ifdef __SSE2__
  // The peak test for four offsets at a time (the same comparisons, NaN included), then only the
  // peaks in order, instead of a branch per offset that noisy responses mispredict.
  const __m128 min_strength = _mm_set1_ps(search.min_strength);
  for (; k + 3 <= origin + range; k += 4) {
    const __m128 r0 = _mm_loadu_ps(response + k);
    const __m128 peak = _mm_and_ps(_mm_and_ps(_mm_cmpge_ps(r0, min_strength),
                                              _mm_cmpge_ps(r0, _mm_loadu_ps(response + k - 1))),
                                   _mm_cmpgt_ps(r0, _mm_loadu_ps(response + k + 1)));
    for (int bits = _mm_movemask_ps(peak); bits != 0; bits &= bits - 1)
      take(k + __builtin_ctz(bits));
  }
#endif
  for (; k <= origin + range; ++k) {
    if (is_peak(k)) take(k);
  }
  return found;
}

int search_edge_map(const ImageView& edges, const Eigen::Vector2d& centre,
                    const Eigen::Vector2d& normal, int range_px, int max_candidates,
                    Candidate* out) {
  int found = 0;
  auto keep = [&](float offset) {
    // Insertion by distance from the centre into the short output list.
    int pos = found < max_candidates ? found : max_candidates;
    while (pos > 0 && std::abs(out[pos - 1].offset) > std::abs(offset)) {
      if (pos < max_candidates) out[pos] = out[pos - 1];
      --pos;
    }
    if (pos < max_candidates) {
      out[pos] = Candidate{offset, 255.0f};
      if (found < max_candidates) ++found;
    }
  };
  const int steps = 4 * range_px;  // half-pixel steps over [−range, range]
  int run_start = -1;
  for (int k = 0; k <= steps; ++k) {
    const double s = 0.5 * k - range_px;
    const double x = centre.x() + s * normal.x(), y = centre.y() + s * normal.y();
    bool hit = false;
    if (x >= 0.0 && y >= 0.0 && x < edges.width - 1.0 && y < edges.height - 1.0) {
      const std::uint8_t* q = edges.data + static_cast<int>(y) * edges.stride + static_cast<int>(x);
      hit = (q[0] | q[1] | q[edges.stride] | q[edges.stride + 1]) != 0;
    }
    if (hit && run_start < 0) run_start = k;
    if ((!hit || k == steps) && run_start >= 0) {
      const int run_end = hit ? k : k - 1;
      keep(static_cast<float>(0.25 * (run_start + run_end) - range_px));
      run_start = -1;
    }
  }
  return found;
}

int search_profile(const ImageView& image, const Eigen::Vector2d& centre,
                   const Eigen::Vector2d& normal, const ProfileSearch& search, float* scratch,
                   Candidate* out) {
  const int half = search.range_px + search.margin();
  const int count = 2 * half + 1;
  sample_profile(image, centre, normal, -half, count, search.band_px, scratch);
  return find_candidates(scratch, half, 0.0f, search, scratch + count, out);
}

}  // namespace sinew::rt
