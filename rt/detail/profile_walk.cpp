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
// All `count` samples (count ≥ 8; returns how many it wrote: count, or 0 below 8), eight at a
// time: per row two 32-bit gathers (the support's top pair and bottom pair, with two spare bytes
// each), then the same integers as sample_sum. When count is not a multiple of eight the last
// block ends at the last sample, overlapping the one before: the overlap is computed twice with
// the same integers, so the profile is the same as the portable walk's; a search line's 23
// samples take three blocks instead of two blocks and seven scalar samples of nine rows each
// (those cost as much as the blocks: 13 % of a whisker tracker's time).
// Each pair's horizontal interpolation (q0 << 8) + fx·(q1 − q0) is computed as
// q0·(256 − fx) + q1·fx, equal in integers, by one multiply-add of 16-bit words (pmaddwd; every
// factor is below 2¹⁵) on the pair moved into its lane's two words: two instructions instead of
// seven per pair, and the positions are one addition per row: the arithmetic, not only the
// gathers, bounded the kernel (bench_whisker_latency's tracking: about 5 % less time).
__attribute__((target("avx2"))) int walk_avx2(const ImageView& image, const ProfileWalk& w,
                                              int count, float* profile) {
  const __m256i lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256i low = _mm256_set1_epi32(255);
  const __m256i full = _mm256_set1_epi32(256);
  // Bytes 0 and 1 of each lane into the low bytes of its two 16-bit words (-1: zero).
  const __m256i pair_to_words =
      _mm256_setr_epi8(0, -1, 1, -1, 4, -1, 5, -1, 8, -1, 9, -1, 12, -1, 13, -1, 0, -1, 1, -1, 4,
                       -1, 5, -1, 8, -1, 9, -1, 12, -1, 13, -1);
  const __m256i stride = _mm256_set1_epi32(static_cast<std::int32_t>(image.stride));
  const __m256 scale = _mm256_set1_ps(scale_of(w));
  const __m256i step_x = _mm256_mullo_epi32(lanes, _mm256_set1_epi32(w.dx));
  const __m256i step_y = _mm256_mullo_epi32(lanes, _mm256_set1_epi32(w.dy));
  const int* top_row = reinterpret_cast<const int*>(image.data);
  const int* bottom_row = reinterpret_cast<const int*>(image.data + image.stride);
  if (count < 8) return 0;
  // Each row's first eight positions, once; a block adds its k·(dx, dy), shared by all rows.
  __m256i row_x[ProfileWalk::kMaxRows], row_y[ProfileWalk::kMaxRows];
  for (int r = 0; r < w.rows; ++r) {
    row_x[r] = _mm256_add_epi32(_mm256_set1_epi32(w.x[r]), step_x);
    row_y[r] = _mm256_add_epi32(_mm256_set1_epi32(w.y[r]), step_y);
  }
  for (int block = 0; block < count; block += 8) {
    // The last block ends at the last sample (see the comment above).
    const int k = block + 8 <= count ? block : count - 8;
    __m256i sum = _mm256_setzero_si256();
    const __m256i block_x = _mm256_set1_epi32(k * w.dx), block_y = _mm256_set1_epi32(k * w.dy);
    for (int r = 0; r < w.rows; ++r) {
      const __m256i X = _mm256_add_epi32(row_x[r], block_x);
      const __m256i Y = _mm256_add_epi32(row_y[r], block_y);
      const __m256i fx = _mm256_and_si256(_mm256_srai_epi32(X, 8), low);
      const __m256i fy = _mm256_and_si256(_mm256_srai_epi32(Y, 8), low);
      const __m256i offset = _mm256_add_epi32(_mm256_mullo_epi32(_mm256_srai_epi32(Y, 16), stride),
                                              _mm256_srai_epi32(X, 16));
      const __m256i a = _mm256_i32gather_epi32(top_row, offset, 1);
      const __m256i b = _mm256_i32gather_epi32(bottom_row, offset, 1);
      // Words (256 − fx, fx) per lane: the weights of the pair's words (q0, q1).
      const __m256i weights =
          _mm256_or_si256(_mm256_slli_epi32(fx, 16), _mm256_sub_epi32(full, fx));
      const __m256i top = _mm256_madd_epi16(_mm256_shuffle_epi8(a, pair_to_words), weights);
      const __m256i bottom = _mm256_madd_epi16(_mm256_shuffle_epi8(b, pair_to_words), weights);
      sum = _mm256_add_epi32(
          sum, _mm256_add_epi32(_mm256_slli_epi32(top, 8),
                                _mm256_mullo_epi32(fy, _mm256_sub_epi32(bottom, top))));
    }
    _mm256_storeu_ps(profile + k, _mm256_mul_ps(_mm256_cvtepi32_ps(sum), scale));
  }
  return count;
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
  if (use_avx2 && avx2_available()) done = walk_avx2(image, walk, count, profile);
#else
  (void)use_avx2;
#endif
  walk_portable(image, walk, done, count, profile);
}

}  // namespace sinew::rt::detail
