#pragma once
/// The k-th smallest of a set of floats (the value std::nth_element puts at place k), by
/// histograms of their bits instead of moving them: a first pass counts the values by the upper 16
/// bits of an order-preserving key, a second pass, per rank asked, by the lower 16 bits within
/// the bin holding that rank. Linear, no copy of the values: whisker detection takes the
/// backlight's percentiles and the contrast map's median this way on every frame (std::nth_element
/// on copies was ~5 % of a run). The same value as nth_element wherever the values hold no NaN and
/// not both zeros (−0 and +0 compare equal there but not here).
/// The histograms are kept between calls (256 KiB each).

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <vector>

namespace sinew::rt::detail {

class FloatSelect {
 public:
  /// First pass: visit(f) is called with a callable that for_each value v calls it(v); returns
  /// how many values were seen.
  template <class Visit>
  std::size_t histogram(Visit&& visit) {
    upper_.assign(kBins, 0);
    std::size_t count = 0;
    std::uint32_t* h = upper_.data();
    visit([&](float v) {
      ++h[key(v) >> 16];
      ++count;
    });
    return count;
  }

  /// The k-th smallest (0-based, k < the count histogram() returned) of the same values, which
  /// visit visits again.
  template <class Visit>
  float kth(std::size_t k, Visit&& visit) {
    std::uint32_t bin = 0;
    while (k >= upper_[bin]) k -= upper_[bin++];
    lower_.assign(kBins, 0);
    std::uint32_t* h = lower_.data();
    visit([&](float v) {
      const std::uint32_t kv = key(v);
      if ((kv >> 16) == bin) ++h[kv & 0xffffu];
    });
    std::uint32_t low = 0;
    while (k >= lower_[low]) k -= lower_[low++];
    return value((bin << 16) | low);
  }

 private:
  static constexpr std::size_t kBins = 1u << 16;
  // Unsigned keys in the floats' order: negative floats' bits inverted, positive ones' sign set.
  static std::uint32_t key(float v) {
    std::uint32_t u;
    std::memcpy(&u, &v, sizeof u);
    return (u & 0x80000000u) ? ~u : (u | 0x80000000u);
  }
  static float value(std::uint32_t k) {
    const std::uint32_t u = (k & 0x80000000u) ? (k & 0x7fffffffu) : ~k;
    float v;
    std::memcpy(&v, &u, sizeof v);
    return v;
  }
  std::vector<std::uint32_t> upper_, lower_;
};

}  // namespace sinew::rt::detail
