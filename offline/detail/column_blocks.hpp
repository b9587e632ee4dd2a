#pragma once
/// Work on the columns of a tall dense matrix split into blocks, the blocks spread over threads:
/// the multi-right-hand-side solves of a Gauss–Newton iteration (Z = one tangent solve per
/// constraint row, L⁺Zᵀ = six Laplacian solves per row). Each block is independent, so a thread
/// takes blocks t, t + T, t + 2T, ... . While the threads run, OpenBLAS is held at one thread of
/// its own (CHOLMOD's supernodal solves call it on small blocks, where its own threads only
/// contend with ours), and restored afterwards.
#include <Eigen/Core>
#include <functional>

namespace sinew::offline::detail {

/// CPUs this process may run on (sched_getaffinity: respects taskset, cgroup cpusets and Slurm's
/// --cpus-per-task), at least 1.
int available_threads();

/// requested ≥ 1: that many threads; 0: available_threads().
int resolve_threads(int requested);

/// Calls work(thread, first_column, block_columns) for every block of at most block columns of
/// [0, columns), from min(threads, #blocks) threads (thread = 0, 1, ...: index per-thread
/// workspaces with it). threads ≥ 1, block ≥ 1. Blocks of one thread run in increasing order.
void for_each_column_block(Eigen::Index columns, Eigen::Index block, int threads,
                           const std::function<void(int, Eigen::Index, Eigen::Index)>& work);

/// Sets Eigen's matrix-product blocking from fixed cache sizes instead of the sizes it reads from
/// the CPU (cpuid) once per process. The blocking decides how a long inner dimension is split
/// and which rows take which micro-kernel, so with the CPU's own sizes a product such as the
/// Woodbury capacitance YᵀY (k = 6m) rounds differently on CPUs with other caches. Idempotent and
/// thread-safe; called by the solvers that need reproducible products.
void use_reproducible_product_blocking();

}  // namespace sinew::offline::detail
