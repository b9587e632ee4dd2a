#include "rt/observation.hpp"

#include <cmath>
#include <limits>

namespace sinew::rt {

int search_profile(const ImageView& image, const Eigen::Vector2d& centre,
                   const Eigen::Vector2d& normal, const ProfileSearch& search, float* scratch,
                   Candidate* out) {
  // Responses at ±range need their neighbours: the central difference reads ±1 more for edges,
  // the centre-surround ±(surround + 1) for lines.
  const int margin = search.mode == ObservationMode::kEdge ? 2 : search.line_surround_px + 2;
  const int half = search.range_px + margin;
  const int count = 2 * half + 1;
  float* profile = scratch;
  float* response = scratch + count;
  const float missing = std::numeric_limits<float>::quiet_NaN();
  const Eigen::Vector2d tangent(normal.y(), -normal.x());
  const int band = search.band_px;

  // Intensity profile, averaged across the band along the tangent (noise ÷ √(2·band + 1)). When the
  // whole sampled parallelogram lies inside the image (its corners do), samples skip the bounds
  // checks; otherwise each is checked and a profile point with a sample outside is missing.
  const Eigen::Vector2d reach = half * normal.cwiseAbs() + band * tangent.cwiseAbs();
  const bool inside = centre.x() - reach.x() >= 0.0 && centre.y() - reach.y() >= 0.0 &&
                      centre.x() + reach.x() < image.width - 1.0 &&
                      centre.y() + reach.y() < image.height - 1.0;
  const float inv = 1.0f / float(2 * band + 1);
  if (inside) {
    // Fast path: all samples inside, walk each band row along the normal in float.
    for (int k = 0; k < count; ++k) profile[k] = 0.0f;
    const float nx = static_cast<float>(normal.x()), ny = static_cast<float>(normal.y());
    const std::ptrdiff_t stride = image.stride;
    for (int b = -band; b <= band; ++b) {
      const float x0 = static_cast<float>(centre.x() + b * tangent.x() - half * normal.x());
      const float y0 = static_cast<float>(centre.y() + b * tangent.y() - half * normal.y());
      for (int k = 0; k < count; ++k) {
        const float x = x0 + k * nx, y = y0 + k * ny;
        const int xi = static_cast<int>(x), yi = static_cast<int>(y);
        const float fx = x - xi, fy = y - yi;
        const std::uint8_t* q = image.data + yi * stride + xi;
        const float top = q[0] + fx * (q[1] - q[0]);
        const float bottom = q[stride] + fx * (q[stride + 1] - q[stride]);
        profile[k] += top + fy * (bottom - top);
      }
    }
    for (int k = 0; k < count; ++k) profile[k] *= inv;
  } else {
    for (int k = 0; k < count; ++k) {
      const Eigen::Vector2d p = centre + double(k - half) * normal;
      float sum = 0.0f;
      int n = 0;
      for (int b = -band; b <= band; ++b) {
        float v;
        if (image.sample(p.x() + b * tangent.x(), p.y() + b * tangent.y(), &v)) {
          sum += v;
          ++n;
        }
      }
      profile[k] = n == 2 * band + 1 ? sum * inv : missing;
    }
  }

  // Response at each offset: signed central difference for edges, centre-surround for lines.
  const int s = search.line_surround_px;
  for (int k = 0; k < count; ++k) {
    response[k] = missing;
    if (search.mode == ObservationMode::kEdge) {
      if (k < 1 || k + 1 >= count) continue;
      const float g = 0.5f * (profile[k + 1] - profile[k - 1]);
      response[k] = search.expected_sign == 0 ? std::abs(g) : g * search.expected_sign;
    } else {
      if (k < s || k + s >= count) continue;
      const float surround = 0.5f * (profile[k - s] + profile[k + s]);
      const float centre_value = 0.25f * (profile[k - 1] + 2.0f * profile[k] + profile[k + 1]);
      const float r = surround - centre_value;  // > 0 at a dark line
      response[k] = search.mode == ObservationMode::kDarkLine ? r : -r;
    }
  }

  // Local maxima within ±range, strongest first (insertion into the short output list).
  int found = 0;
  for (int k = half - search.range_px; k <= half + search.range_px; ++k) {
    const float r0 = response[k], rm = response[k - 1], rp = response[k + 1];
    if (!(r0 >= search.min_strength) || !(r0 >= rm) || !(r0 > rp)) continue;  // NaN fails too
    const float denom = rm - 2.0f * r0 + rp;
    float delta = denom < 0.0f ? 0.5f * (rm - rp) / denom : 0.0f;
    if (delta > 0.5f) delta = 0.5f;
    if (delta < -0.5f) delta = -0.5f;
    Candidate c{float(k - half) + delta, r0};
    int pos = found < search.max_candidates ? found : search.max_candidates;
    while (pos > 0 && out[pos - 1].strength < c.strength) {
      if (pos < search.max_candidates) out[pos] = out[pos - 1];
      --pos;
    }
    if (pos < search.max_candidates) {
      out[pos] = c;
      if (found < search.max_candidates) ++found;
    }
  }
  return found;
}

}  // namespace sinew::rt
