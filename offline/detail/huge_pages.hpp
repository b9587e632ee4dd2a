#pragma once
/// Large dense work matrices (Zᵀ, L⁺Zᵀ, K⁻¹Aᵀ: gigabytes at 40k tets) backed by transparent huge
/// pages. Debian's default THP mode is "madvise": without the advice every 4 KiB page of a fresh
/// matrix costs a page fault on first touch, and on this virtual machine those faults took a third
/// of a Gauss–Newton iteration (bench_gauss_newton, docs/registration.md).
#include <Eigen/Core>

namespace sinew::offline::detail {

/// A rows x cols matrix, not initialised, whose 2 MiB-aligned part the kernel is asked (madvise
/// MADV_HUGEPAGE) to back with huge pages before anything touches it; where the advice is not
/// available the matrix is just a matrix.
Eigen::MatrixXd large_matrix(Eigen::Index rows, Eigen::Index cols);

}  // namespace sinew::offline::detail
