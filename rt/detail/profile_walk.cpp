#include "rt/detail/profile_walk.hpp"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define SINEW_PROFILE_AVX2 1
#include <immintrin.h>
#endif

namespace sinew::rt::detail {

namespace {

// One sample: the sum over rows of the bilinear value ×2¹⁶ (≤ 255·2¹⁶ per row, so 21 rows fit in
// 31 bits), all in integers.
inline std::int32_t sample_sum(const ImageView& image, const ProfileWalk& w, int k) {
  const std::ptrdiff_t stride = image.stride;
  std::int32_t sum = 0;
  for (int r = 0; r < w.rows; ++r) {
    const std::int32_t X = w.x[r] + k * w.dx, Y = w.y[r] + k * w.dy;
    const std::int32_t fx = (X >> 8) & 255, fy = (Y >> 8) & 255;
    const std::uint8_t* q = image.data + std::ptrdiff_t(Y >> 16) * stride + (X >> 16);
    const std::int32_t top = (q[0] << 8) + fx * (q[1] - q[0]);
    const std::int32_t bottom = (q[stride] << 8) + fx * (q[stride + 1] - q[stride]);
    sum += (top << 8) + fy * (bottom - top);
  }
  return sum;
}

inline float scale_of(const ProfileWalk& w) {
  return 1.0f / (65536.0f * float(w.rows));
}

void walk_portable(const ImageView& image, const ProfileWalk& w, int first, int count,
                   float* profile) {
  const float scale = scale_of(w);
  for (int k = first; k < count; ++k)
    profile[k] = static_cast<float>(sample_sum(image, w, k)) * scale;
}

#ifdef SINEW_PROFILE_AVX2
// Eight samples at a time: per row two 32-bit gathers (the support's top pair and bottom pair,
// with two spare bytes each), then the same integer arithmetic as sample_sum.
__attribute__((target("avx2"))) int walk_avx2(const ImageView& image, const ProfileWalk& w,
                                              int count, float* profile) {
  const __m256i lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256i low = _mm256_set1_epi32(255);
  const __m256i stride = _mm256_set1_epi32(static_cast<std::int32_t>(image.stride));
  const __m256 scale = _mm256_set1_ps(scale_of(w));
  const __m256i step_x = _mm256_mullo_epi32(lanes, _mm256_set1_epi32(w.dx));
  const __m256i step_y = _mm256_mullo_epi32(lanes, _mm256_set1_epi32(w.dy));
  const int* top_row = reinterpret_cast<const int*>(image.data);
  const int* bottom_row = reinterpret_cast<const int*>(image.data + image.stride);
  int k = 0;
  for (; k + 8 <= count; k += 8) {
    __m256i sum = _mm256_setzero_si256();
    for (int r = 0; r < w.rows; ++r) {
      const __m256i X = _mm256_add_epi32(_mm256_set1_epi32(w.x[r] + k * w.dx), step_x);
      const __m256i Y = _mm256_add_epi32(_mm256_set1_epi32(w.y[r] + k * w.dy), step_y);
      const __m256i fx = _mm256_and_si256(_mm256_srai_epi32(X, 8), low);
      const __m256i fy = _mm256_and_si256(_mm256_srai_epi32(Y, 8), low);
      const __m256i offset = _mm256_add_epi32(_mm256_mullo_epi32(_mm256_srai_epi32(Y, 16), stride),
                                              _mm256_srai_epi32(X, 16));
      const __m256i a = _mm256_i32gather_epi32(top_row, offset, 1);
      const __m256i b = _mm256_i32gather_epi32(bottom_row, offset, 1);
      const __m256i q0 = _mm256_and_si256(a, low);
      const __m256i q1 = _mm256_and_si256(_mm256_srli_epi32(a, 8), low);
      const __m256i q2 = _mm256_and_si256(b, low);
      const __m256i q3 = _mm256_and_si256(_mm256_srli_epi32(b, 8), low);
      const __m256i top = _mm256_add_epi32(_mm256_slli_epi32(q0, 8),
                                           _mm256_mullo_epi32(fx, _mm256_sub_epi32(q1, q0)));
      const __m256i bottom = _mm256_add_epi32(_mm256_slli_epi32(q2, 8),
                                              _mm256_mullo_epi32(fx, _mm256_sub_epi32(q3, q2)));
      sum = _mm256_add_epi32(
          sum, _mm256_add_epi32(_mm256_slli_epi32(top, 8),
                                _mm256_mullo_epi32(fy, _mm256_sub_epi32(bottom, top))));
    }
    _mm256_storeu_ps(profile + k, _mm256_mul_ps(_mm256_cvtepi32_ps(sum), scale));
  }
  return k;
}

// All `count` samples (count ≥ 8): the blocks of eight, then one more block ending at the last
// sample, overlapping the previous one. The overlap is computed twice with the same integers, so
// the profile is the same as the portable walk's; a search line's 23 samples take three blocks
// instead of two blocks and seven scalar samples of nine rows each (those cost as much as the
// blocks: 13 % of a whisker tracker's time).
__attribute__((target("avx2"))) void walk_avx2_all(const ImageView& image, const ProfileWalk& w,
                                                   int count, float* profile) {
  const int done = walk_avx2(image, w, count, profile);
  if (done == count) return;
  ProfileWalk tail = w;
  const int first = count - 8;
  for (int r = 0; r < w.rows; ++r) {
    tail.x[r] = w.x[r] + first * w.dx;
    tail.y[r] = w.y[r] + first * w.dy;
  }
  walk_avx2(image, tail, 8, profile + first);
}
#endif

}  // namespace

bool avx2_available() {
#ifdef SINEW_PROFILE_AVX2
  static const bool available = __builtin_cpu_supports("avx2");
  return available;
#else
  return false;
#endif
}

void walk_profile(const ImageView& image, const ProfileWalk& walk, int count, float* profile,
                  bool use_avx2) {
  int done = 0;
#ifdef SINEW_PROFILE_AVX2
  if (use_avx2 && avx2_available()) {
    if (count >= 8) {
      walk_avx2_all(image, walk, count, profile);
      return;
    }
    done = walk_avx2(image, walk, count, profile);
  }
#else
  (void)use_avx2;
#endif
  walk_portable(image, walk, done, count, profile);
}

}  // namespace sinew::rt::detail
