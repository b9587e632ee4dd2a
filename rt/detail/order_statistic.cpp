#include "rt/detail/order_statistic.hpp"

#include <algorithm>
#include <utility>

namespace sinew::rt::detail {

namespace {

// Moves the elements of v[lo, hi] for which below(x) holds to the front, keeping the range's
// elements; returns the first index where below fails. Branch-free: every element is swapped with
// the boundary, which only advances past elements that belong in front.
template <class Below>
int partition(float* v, int lo, int hi, Below below) {
  int store = lo;
  for (int i = lo; i <= hi; ++i) {
    const float x = v[i];
    const bool front = below(x);
    v[i] = v[store];
    v[store] = x;
    store += front ? 1 : 0;
  }
  return store;
}

}  // namespace

float kth_smallest(float* v, int n, int k) {
  int lo = 0, hi = n - 1;
  while (hi - lo > 16) {
    // Median of three as the pivot, then three ways: < pivot, == pivot, > pivot. The pivot is
    // an element of the range, so the middle part is never empty and the range always shrinks.
    const float a = v[lo], b = v[lo + (hi - lo) / 2], c = v[hi];
    const float pivot = std::max(std::min(a, b), std::min(std::max(a, b), c));
    const int less = partition(v, lo, hi, [pivot](float x) { return x < pivot; });
    const int equal = partition(v, less, hi, [pivot](float x) { return x <= pivot; });
    if (k < less) {
      hi = less - 1;
    } else if (k < equal) {
      return pivot;
    } else {
      lo = equal;
    }
  }
  // A short range: insertion sort.
  for (int i = lo + 1; i <= hi; ++i) {
    const float x = v[i];
    int j = i;
    for (; j > lo && v[j - 1] > x; --j) v[j] = v[j - 1];
    v[j] = x;
  }
  return v[k];
}

}  // namespace sinew::rt::detail
