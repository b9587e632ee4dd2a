/// rt/detail/order_statistic: the branch-free quickselect gives std::nth_element's value.
#include "rt/detail/order_statistic.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

namespace sinew::rt::detail {
namespace {

TEST(OrderStatistic, KthSmallestEqualsNthElementOnRandomTiedAndSortedInput) {
  std::mt19937 gen(7);
  std::uniform_real_distribution<float> uniform(0.0f, 10.0f);
  std::uniform_int_distribution<int> few(0, 3);
  for (int n : {1, 2, 3, 16, 17, 18, 100, 257, 1000}) {
    for (int kind = 0; kind < 4; ++kind) {
      std::vector<float> v(n);
      for (int i = 0; i < n; ++i) {
        v[i] = kind == 0   ? uniform(gen)                       // distinct
               : kind == 1 ? static_cast<float>(few(gen))       // many ties
               : kind == 2 ? static_cast<float>(i)              // sorted
                           : static_cast<float>(n - i) * 0.5f;  // reversed
      }
      for (int k : {0, n / 2, n - 1}) {
        std::vector<float> a = v, b = v;
        std::nth_element(b.begin(), b.begin() + k, b.end());
        EXPECT_EQ(kth_smallest(a.data(), n, k), b[k])
            << "n " << n << " kind " << kind << " k " << k;
        std::sort(a.begin(), a.end());
        std::sort(b.begin(), b.end());
        EXPECT_EQ(a, b) << "the values are only reordered";
      }
    }
  }
}

}  // namespace
}  // namespace sinew::rt::detail
