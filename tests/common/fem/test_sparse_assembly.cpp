// Tests of common/fem/sparse_assembly: the pattern analysed once, the scatter map, reuse without
// allocation, upper-triangle storage and vector assembly.

#include "common/fem/sparse_assembly.hpp"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cstdlib>

// The one translation unit of this executable that includes it: it defines malloc and operator
// new hooks, to prove that assemble() does not allocate.
#include "tests/support/allocation_counter.hpp"
#include "tests/support/finite_difference.hpp"
#include "tests/support/tet_mesh_fixtures.hpp"

namespace {

using sinew::common::AssemblyStatus;
using sinew::common::PatternStorage;
using sinew::common::SparseAssembly;

using sinew::testing::AllocationCounter;

// Random element matrices, stacked side by side: (3k) by (3k·#E). Non-symmetric unless asked, so
// a transposed scatter would be caught; upper-triangle storage needs symmetric ones.
Eigen::MatrixXd random_element_matrices(Eigen::Index num_elements, int element_dofs,
                                        std::mt19937& gen, bool symmetric = false) {
  Eigen::MatrixXd all(element_dofs, element_dofs * num_elements);
  for (Eigen::Index e = 0; e < num_elements; ++e) {
    const Eigen::MatrixXd A = Eigen::Map<const Eigen::MatrixXd>(
        sinew::testing::random_vector(element_dofs * element_dofs, 1.0, gen).data(), element_dofs,
        element_dofs);
    all.middleCols(element_dofs * e, element_dofs) =
        symmetric ? Eigen::MatrixXd(A + A.transpose()) : A;
  }
  return all;
}

// Reference: dense assembly by explicit index arithmetic.
Eigen::MatrixXd dense_assembly(const Eigen::MatrixXi& elements, Eigen::Index num_vertices,
                               const Eigen::MatrixXd& element_matrices) {
  const Eigen::Index m = 3 * elements.cols();
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(3 * num_vertices, 3 * num_vertices);
  for (Eigen::Index e = 0; e < elements.rows(); ++e) {
    for (Eigen::Index r = 0; r < m; ++r) {
      for (Eigen::Index c = 0; c < m; ++c) {
        K(3 * elements(e, r / 3) + r % 3, 3 * elements(e, c / 3) + c % 3) +=
            element_matrices(r, m * e + c);
      }
    }
  }
  return K;
}

TEST(SparseAssembly, AssembledMatrixEqualsDenseAssembly) {
  auto& gen = sinew::testing::rng();
  const auto mesh = sinew::testing::make_box_mesh(2, 2, 1);
  const Eigen::Index n = mesh.rest_positions.rows();
  SparseAssembly assembly;
  ASSERT_EQ(assembly.analyse(mesh.tets, n), AssemblyStatus::kOk);
  EXPECT_EQ(assembly.num_dofs(), 3 * n);
  EXPECT_EQ(assembly.element_dofs(), 12);
  EXPECT_TRUE(assembly.matrix().isCompressed());

  const Eigen::MatrixXd Ke = random_element_matrices(mesh.tets.rows(), 12, gen);
  ASSERT_EQ(assembly.assemble(Ke), AssemblyStatus::kOk);
  const Eigen::MatrixXd expected = dense_assembly(mesh.tets, n, Ke);
  EXPECT_LT((Eigen::MatrixXd(assembly.matrix()) - expected).norm(), 1e-13 * expected.norm());
  // The pattern is the union of the element blocks: 3x3 blocks for vertex pairs sharing a tet.
  Eigen::MatrixXi adjacency = Eigen::MatrixXi::Zero(n, n);
  for (Eigen::Index t = 0; t < mesh.tets.rows(); ++t) {
    for (int a = 0; a < 4; ++a) {
      for (int b = 0; b < 4; ++b) adjacency(mesh.tets(t, a), mesh.tets(t, b)) = 1;
    }
  }
  EXPECT_EQ(assembly.matrix().nonZeros(), 9 * adjacency.sum());
}

TEST(SparseAssembly, SecondAssembleReusesPatternWithoutAllocating) {
  auto& gen = sinew::testing::rng();
  const auto mesh = sinew::testing::make_box_mesh(2, 1, 1);
  const Eigen::Index n = mesh.rest_positions.rows();
  SparseAssembly assembly;
  ASSERT_EQ(assembly.analyse(mesh.tets, n), AssemblyStatus::kOk);
  ASSERT_EQ(assembly.assemble(random_element_matrices(mesh.tets.rows(), 12, gen)),
            AssemblyStatus::kOk);
  const auto& K = assembly.matrix();
  const Eigen::Index nnz = K.nonZeros();
  const double* values = K.valuePtr();
  const int* inner = K.innerIndexPtr();
  const int* outer = K.outerIndexPtr();

  const Eigen::MatrixXd Ke = random_element_matrices(mesh.tets.rows(), 12, gen);
  long allocations = 0;
  AssemblyStatus statuses[3];
  {
    AllocationCounter counter;
    for (AssemblyStatus& status : statuses) status = assembly.assemble(Ke);
    for (Eigen::Index t = 0; t < mesh.tets.rows(); ++t) {
      const sinew::common::Matrix12d fixed = Ke.middleCols<12>(12 * t);
      assembly.add_element_matrix(t, fixed);  // fixed-size input binds without a copy
    }
    allocations = counter.total();
  }
  for (const AssemblyStatus status : statuses) EXPECT_EQ(status, AssemblyStatus::kOk);
  if (sinew::testing::allocation_counting_available()) {
    EXPECT_EQ(allocations, 0);
  }
  EXPECT_EQ(K.nonZeros(), nnz);
  EXPECT_EQ(K.valuePtr(), values);
  EXPECT_EQ(K.innerIndexPtr(), inner);
  EXPECT_EQ(K.outerIndexPtr(), outer);
  const Eigen::MatrixXd expected = 2.0 * dense_assembly(mesh.tets, n, Ke);
  EXPECT_LT((Eigen::MatrixXd(K) - expected).norm(), 1e-13 * expected.norm());
}

TEST(SparseAssembly, AllocationCounterSeesAllocations) {
  // Guard for the test above: the counter is not blind.
  if (!sinew::testing::allocation_counting_available())
    GTEST_SKIP() << sinew::testing::kAllocationCountingUnavailable;
  long allocations = 0;
  {
    AllocationCounter counter;
    Eigen::VectorXd v(1000);
    double* volatile escaped = v.data();  // keeps the allocation from being optimised away
    (void)escaped;
    allocations = counter.total();
  }
  EXPECT_GT(allocations, 0);
  // And it sees plain malloc, which Eigen uses, not only operator new.
  {
    AllocationCounter counter;
    void* volatile p = std::malloc(64);
    std::free(p);
    allocations = counter.total();
  }
  EXPECT_EQ(allocations, 1);
}

TEST(SparseAssembly, UpperStorageHoldsUpperTriangle) {
  auto& gen = sinew::testing::rng();
  const auto mesh = sinew::testing::make_box_mesh(1, 2, 1);
  const Eigen::Index n = mesh.rest_positions.rows();
  SparseAssembly full;
  SparseAssembly upper;
  ASSERT_EQ(full.analyse(mesh.tets, n), AssemblyStatus::kOk);
  ASSERT_EQ(upper.analyse(mesh.tets, n, PatternStorage::kUpper), AssemblyStatus::kOk);
  const Eigen::MatrixXd Ke = random_element_matrices(mesh.tets.rows(), 12, gen, true);
  ASSERT_EQ(upper.assemble(Ke), AssemblyStatus::kOk);
  const Eigen::MatrixXd expected = dense_assembly(mesh.tets, n, Ke);
  const Eigen::MatrixXd stored = upper.matrix();
  EXPECT_EQ(stored.triangularView<Eigen::StrictlyLower>().toDenseMatrix().norm(), 0.0);
  EXPECT_LT((stored.triangularView<Eigen::Upper>().toDenseMatrix() -
             Eigen::MatrixXd(expected.triangularView<Eigen::Upper>()))
                .norm(),
            1e-13 * expected.norm());
  const Eigen::SparseMatrix<double> symmetric_sparse =
      upper.matrix().selfadjointView<Eigen::Upper>();
  const Eigen::MatrixXd symmetric = symmetric_sparse;
  EXPECT_LT((symmetric - expected).norm(), 1e-13 * expected.norm());
  EXPECT_EQ(upper.matrix().nonZeros(), (full.matrix().nonZeros() + 3 * n) / 2);
}

TEST(SparseAssembly, VectorAssemblyEqualsDenseScatter) {
  auto& gen = sinew::testing::rng();
  const auto mesh = sinew::testing::make_box_mesh(2, 1, 1);
  const Eigen::Index n = mesh.rest_positions.rows();
  SparseAssembly assembly;
  ASSERT_EQ(assembly.analyse(mesh.tets, n), AssemblyStatus::kOk);
  const Eigen::MatrixXd ge = Eigen::Map<const Eigen::MatrixXd>(
      sinew::testing::random_vector(12 * mesh.tets.rows(), 1.0, gen).data(), 12, mesh.tets.rows());
  Eigen::VectorXd expected = Eigen::VectorXd::Zero(3 * n);
  for (Eigen::Index t = 0; t < mesh.tets.rows(); ++t) {
    for (int r = 0; r < 12; ++r) expected(3 * mesh.tets(t, r / 3) + r % 3) += ge(r, t);
  }
  Eigen::VectorXd global = Eigen::VectorXd::Constant(3 * n, 7.0);  // overwritten, not added to
  ASSERT_EQ(assembly.assemble_vector(ge, global), AssemblyStatus::kOk);
  EXPECT_LT((global - expected).norm(), 1e-14 * expected.norm());
  EXPECT_GT(expected.norm(), 0.0);
}

TEST(SparseAssembly, GenericVerticesPerElement) {
  // Two-vertex elements (bars, 6x6 matrices) on a chain 0-1-2-3 plus a bar 0-3.
  auto& gen = sinew::testing::rng();
  Eigen::MatrixXi bars(4, 2);
  bars << 0, 1, 1, 2, 2, 3, 3, 0;
  SparseAssembly assembly;
  ASSERT_EQ(assembly.analyse(bars, 4), AssemblyStatus::kOk);
  EXPECT_EQ(assembly.element_dofs(), 6);
  const Eigen::MatrixXd Ke = random_element_matrices(4, 6, gen);
  ASSERT_EQ(assembly.assemble(Ke), AssemblyStatus::kOk);
  const Eigen::MatrixXd expected = dense_assembly(bars, 4, Ke);
  EXPECT_LT((Eigen::MatrixXd(assembly.matrix()) - expected).norm(), 1e-13 * expected.norm());
  EXPECT_EQ(assembly.matrix().nonZeros(), 9 * (4 + 2 * 4));  // diagonal blocks + 4 edges
}

TEST(SparseAssembly, InvalidInputIsReported) {
  SparseAssembly assembly;
  EXPECT_EQ(assembly.assemble(Eigen::MatrixXd::Zero(12, 12)), AssemblyStatus::kNotAnalysed);
  auto mesh = sinew::testing::make_box_mesh(1, 1, 1);
  mesh.tets(4, 1) = -1;
  EXPECT_EQ(assembly.analyse(mesh.tets, mesh.rest_positions.rows()),
            AssemblyStatus::kIndexOutOfRange);
  ASSERT_TRUE(assembly.bad_element());
  EXPECT_EQ(*assembly.bad_element(), 4);
  EXPECT_EQ(assembly.status(), AssemblyStatus::kIndexOutOfRange);
  mesh.tets(4, 1) = 0;
  ASSERT_EQ(assembly.analyse(mesh.tets, mesh.rest_positions.rows()), AssemblyStatus::kOk);
  EXPECT_EQ(assembly.assemble(Eigen::MatrixXd::Zero(12, 11)), AssemblyStatus::kInvalidDimensions);
  Eigen::VectorXd wrong_size(5);
  EXPECT_EQ(assembly.assemble_vector(Eigen::MatrixXd::Zero(12, 6), wrong_size),
            AssemblyStatus::kInvalidDimensions);
}

TEST(SparseAssembly, DofVectorRoundTrip) {
  const auto mesh = sinew::testing::make_box_mesh(1, 1, 2);
  const Eigen::VectorXd x = sinew::common::to_dof_vector(mesh.rest_positions);
  ASSERT_EQ(x.size(), 3 * mesh.rest_positions.rows());
  EXPECT_EQ(x.segment<3>(3 * 5), mesh.rest_positions.row(5).transpose());
  EXPECT_EQ(sinew::common::to_positions(x), mesh.rest_positions);
}

}  // namespace
