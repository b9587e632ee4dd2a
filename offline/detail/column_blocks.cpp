#include "offline/detail/column_blocks.hpp"

#include <sched.h>

#include <algorithm>
#include <mutex>
#include <thread>
#include <vector>

extern "C" {
// OpenBLAS's thread controls (libopenblas is linked explicitly, see cmake/SinewDependencies.cmake).
void openblas_set_num_threads(int num_threads);
int openblas_get_num_threads(void);
}

namespace sinew::offline::detail {

int available_threads() {
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof(set), &set) == 0) return std::max(1, CPU_COUNT(&set));
  return std::max(1u, std::thread::hardware_concurrency());
}

int resolve_threads(int requested) {
  return requested >= 1 ? requested : available_threads();
}

void for_each_column_block(Eigen::Index columns, Eigen::Index block, int threads,
                           const std::function<void(int, Eigen::Index, Eigen::Index)>& work) {
  const Eigen::Index blocks = (columns + block - 1) / block;
  const int used = static_cast<int>(std::min<Eigen::Index>(std::max(threads, 1), blocks));
  auto run = [&](int thread) {
    for (Eigen::Index b = thread; b < blocks; b += used) {
      const Eigen::Index first = b * block;
      work(thread, first, std::min(block, columns - first));
    }
  };
  if (used <= 1) {
    run(0);
    return;
  }
  const int blas_threads = openblas_get_num_threads();
  openblas_set_num_threads(1);
  std::vector<std::thread> pool;
  for (int thread = 1; thread < used; ++thread) pool.emplace_back(run, thread);
  run(0);
  for (std::thread& t : pool) t.join();
  openblas_set_num_threads(blas_threads);
}

void use_reproducible_product_blocking() {
  static std::once_flag once;
  // Typical x86-64 sizes (L1d 32 KiB, L2 512 KiB, L3 4 MiB): the same blocking everywhere.
  std::call_once(once, [] { Eigen::setCpuCacheSizes(32 * 1024, 512 * 1024, 4 * 1024 * 1024); });
}

}  // namespace sinew::offline::detail
