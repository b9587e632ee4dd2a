// rt/whisker/detail/float_select.hpp against std::nth_element, bit for bit.
#include "rt/whisker/detail/float_select.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <random>
#include <vector>

namespace sinew::rt::detail {
namespace {

float nth(std::vector<float> v, std::size_t k) {
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

bool same_bits(float a, float b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

TEST(FloatSelect, EveryRankAsNthElementOnRandomSetsWithTies) {
  std::mt19937 rng(5);
  FloatSelect select;
  for (const int n : {1, 2, 7, 100, 1000}) {
    for (const int kind : {0, 1, 2}) {
      std::vector<float> v(static_cast<std::size_t>(n));
      std::uniform_real_distribution<float> wide(-300.0f, 300.0f);
      std::uniform_int_distribution<int> grey(0, 9);
      for (float& x : v) {
        // positive and negative; few distinct values (ties); tiny values in one upper bin
        x = kind == 0   ? wide(rng)
            : kind == 1 ? static_cast<float>(grey(rng)) * 0.5f + 1.0f
                        : 1.0f + 1e-6f * static_cast<float>(grey(rng));
      }
      auto visit = [&](auto&& f) {
        for (float x : v) f(x);
      };
      ASSERT_EQ(select.histogram(visit), v.size());
      for (std::size_t k = 0; k < v.size(); k += std::max<std::size_t>(1, v.size() / 37)) {
        EXPECT_TRUE(same_bits(select.kth(k, visit), nth(v, k))) << n << " " << kind << " " << k;
      }
    }
  }
}

TEST(FloatSelect, MedianOfAKnownSet) {
  const std::vector<float> v = {3.5f, -1.0f, 8.0f, 0.25f, 2.0f};
  FloatSelect select;
  auto visit = [&](auto&& f) {
    for (float x : v) f(x);
  };
  select.histogram(visit);
  EXPECT_EQ(select.kth(2, visit), 2.0f);
  EXPECT_EQ(select.kth(0, visit), -1.0f);
  EXPECT_EQ(select.kth(4, visit), 8.0f);
  EXPECT_NE(select.kth(3, visit), 2.0f);  // the check can fail
}

}  // namespace
}  // namespace sinew::rt::detail
