#pragma once
/// Large dense work matrices (Zᵀ, L⁺Zᵀ, K⁻¹Aᵀ: gigabytes at 40k tets) backed by transparent huge
/// pages. Debian's default THP mode is "madvise": without the advice every 4 KiB page of a fresh
/// matrix costs a page fault on first touch, and on this virtual machine those faults took a third
/// of a Gauss–Newton iteration (bench_gauss_newton, docs/registration.md).
#include <Eigen/Core>

namespace sinew::offline::detail {

/// Asks the kernel (madvise MADV_HUGEPAGE) to back the whole 2 MiB-aligned part of
/// [data, data + count) with huge pages. Only useful before the memory is first written; a no-op
/// where the advice is not available (the call can fail without harm).
void advise_huge_pages(double* data, Eigen::Index count);

/// A rows x cols matrix, not initialised, advised as above before anything touches it.
Eigen::MatrixXd large_matrix(Eigen::Index rows, Eigen::Index cols);

}  // namespace sinew::offline::detail
