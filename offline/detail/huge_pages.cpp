#include "offline/detail/huge_pages.hpp"

#include <sys/mman.h>

#include <cstdint>

namespace sinew::offline::detail {
namespace {

// Only useful before the memory is first written; the call can fail without harm.
void advise_huge_pages(double* data, Eigen::Index count) {
#ifdef MADV_HUGEPAGE
  constexpr std::uintptr_t kHuge = std::uintptr_t{1} << 21;
  const auto begin = reinterpret_cast<std::uintptr_t>(data);
  const std::uintptr_t end = begin + static_cast<std::uintptr_t>(count) * sizeof(double);
  const std::uintptr_t first = (begin + kHuge - 1) & ~(kHuge - 1);
  const std::uintptr_t last = end & ~(kHuge - 1);
  if (data == nullptr || last <= first) return;
  madvise(reinterpret_cast<void*>(first), last - first, MADV_HUGEPAGE);
#else
  (void)data;
  (void)count;
#endif
}

}  // namespace

Eigen::MatrixXd large_matrix(Eigen::Index rows, Eigen::Index cols) {
  Eigen::MatrixXd matrix(rows, cols);
  advise_huge_pages(matrix.data(), matrix.size());
  return matrix;
}

}  // namespace sinew::offline::detail
