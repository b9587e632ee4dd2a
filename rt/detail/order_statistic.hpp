#pragma once
/// The k-th smallest of a few hundred floats, for the tracker's robust scale (the median absolute
/// residual, once per Newton step). A quickselect whose partitions are branch-free: residuals are
/// in random order, so std::nth_element's branches mispredict about every other element (measured:
/// a tenth of the per-frame time at 16 elements). Same value as std::nth_element; no allocation.

namespace sinew::rt::detail {

/// Returns the k-th smallest (0-based) of values[0, n), 0 ≤ k < n, reordering values. No NaNs.
float kth_smallest(float* values, int n, int k);

}  // namespace sinew::rt::detail
