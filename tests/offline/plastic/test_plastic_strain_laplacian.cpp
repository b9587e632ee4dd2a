// Tests of offline/plastic_strain_laplacian: face adjacency of tets, the scalar tet Laplacian
// (seed 003, eq. 29), its 6-expansion with the √2 weights (eq. 30), symmetry, the six nullspace
// vectors ψ_i of the lemma of appendix A, and smoothing behaviour on smooth and rough fields.

#include "offline/plastic/plastic_strain_laplacian.hpp"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <cmath>

#include "offline/plastic/plastic_strain.hpp"
#include "tests/support/finite_difference.hpp"
#include "tests/support/tet_mesh_fixtures.hpp"

namespace {

using sinew::common::TetIndices;

TEST(TetFaceAdjacency, PairsComponentsAndInvalidInput) {
  TetIndices two(2, 4);
  two << 0, 1, 2, 3,  //
      1, 2, 3, 4;     // shares face {1, 2, 3}
  auto adjacency = sinew::offline::tet_face_adjacency(two);
  ASSERT_TRUE(adjacency.ok());
  ASSERT_EQ(adjacency.pairs.rows(), 1);
  EXPECT_EQ(adjacency.pairs(0, 0), 0);
  EXPECT_EQ(adjacency.pairs(0, 1), 1);
  EXPECT_EQ(adjacency.num_components, 1);

  TetIndices apart(3, 4);
  apart << 0, 1, 2, 3,  //
      1, 2, 3, 4,       //
      5, 6, 7, 8;       // no shared face
  adjacency = sinew::offline::tet_face_adjacency(apart);
  EXPECT_EQ(adjacency.pairs.rows(), 1);
  EXPECT_EQ(adjacency.num_components, 2);

  TetIndices edge_only(2, 4);
  edge_only << 0, 1, 2, 3,  //
      0, 1, 4, 5;           // shares only an edge: not adjacent
  EXPECT_EQ(sinew::offline::tet_face_adjacency(edge_only).pairs.rows(), 0);

  TetIndices fan(3, 4);
  fan << 0, 1, 2, 3,  //
      0, 1, 2, 4,     //
      0, 1, 2, 5;     // face {0, 1, 2} shared by three tets
  adjacency = sinew::offline::tet_face_adjacency(fan);
  EXPECT_EQ(adjacency.non_manifold_faces, 1);
  EXPECT_EQ(adjacency.pairs.rows(), 3);

  TetIndices repeated(1, 4);
  repeated << 0, 1, 1, 2;
  adjacency = sinew::offline::tet_face_adjacency(repeated);
  EXPECT_EQ(adjacency.status, sinew::offline::TetAdjacencyStatus::kRepeatedVertex);
  ASSERT_TRUE(adjacency.bad_tet);
  EXPECT_EQ(*adjacency.bad_tet, 0);
  TetIndices negative(1, 4);
  negative << 0, 1, -2, 3;
  EXPECT_EQ(sinew::offline::tet_face_adjacency(negative).status,
            sinew::offline::TetAdjacencyStatus::kNegativeIndex);
}

TEST(PlasticStrainLaplacian, BoxMeshAdjacencyCountsFaces) {
  const auto mesh = sinew::testing::make_box_mesh(2, 2, 2);
  const auto laplacian = sinew::offline::make_plastic_strain_laplacian(mesh.tets);
  ASSERT_TRUE(laplacian.ok());
  const Eigen::Index m = mesh.tets.rows();  // 48
  // Boundary: 6 sides of 2x2 squares, each square cut into 2 triangles.
  const Eigen::Index boundary_faces = 6 * 4 * 2;
  EXPECT_EQ(laplacian.adjacency.pairs.rows(), (4 * m - boundary_faces) / 2);
  EXPECT_EQ(laplacian.adjacency.num_components, 1);
  EXPECT_EQ(laplacian.adjacency.non_manifold_faces, 0);

  const Eigen::MatrixXd L_sc = laplacian.scalar;
  EXPECT_LT(L_sc.rowwise().sum().norm(), 1e-14);
  EXPECT_LE(L_sc.diagonal().maxCoeff(), 4.0);
  EXPECT_GE(L_sc.diagonal().minCoeff(), 1.0);
  EXPECT_EQ(L_sc, L_sc.transpose());
}

TEST(PlasticStrainLaplacian, IsSymmetricWithTheSqrtTwoWeights) {
  const auto mesh = sinew::testing::make_box_mesh(2, 1, 1);
  const auto laplacian = sinew::offline::make_plastic_strain_laplacian(mesh.tets);
  ASSERT_TRUE(laplacian.ok());
  const Eigen::Index m = mesh.tets.rows();
  const Eigen::MatrixXd L = laplacian.matrix;
  const Eigen::MatrixXd L_sc = laplacian.scalar;
  ASSERT_EQ(L.rows(), 6 * m);
  EXPECT_EQ(L, L.transpose());
  const auto& w = sinew::offline::plastic_strain_laplacian_weights();
  EXPECT_EQ(w[0], 1.0);
  EXPECT_EQ(w[1], std::sqrt(2.0));
  EXPECT_EQ(w[2], std::sqrt(2.0));
  EXPECT_EQ(w[3], 1.0);
  EXPECT_EQ(w[4], std::sqrt(2.0));
  EXPECT_EQ(w[5], 1.0);
  for (Eigen::Index i = 0; i < m; ++i) {
    for (Eigen::Index j = 0; j < m; ++j) {
      for (int k = 0; k < 6; ++k) {
        for (int l = 0; l < 6; ++l) {
          const double expected = k == l ? w[k] * L_sc(i, j) : 0.0;
          ASSERT_EQ(L(6 * i + k, 6 * j + l), expected) << i << " " << j << " " << k << " " << l;
        }
      }
    }
  }

  // ‖L s‖² is the squared Frobenius norm of L^sc applied entrywise to the symmetric Fp field: the
  // off-diagonal components count twice.
  auto& gen = sinew::testing::rng();
  const Eigen::VectorXd s = sinew::testing::random_vector(6 * m, 1.0, gen);
  double frobenius = 0.0;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      Eigen::VectorXd entry(m);
      for (Eigen::Index t = 0; t < m; ++t) {
        entry[t] = sinew::offline::plastic_strain_matrix(s.segment<6>(6 * t))(r, c);
      }
      frobenius += (L_sc * entry).squaredNorm();
    }
  }
  EXPECT_NEAR((L * s).squaredNorm(), frobenius, 1e-10 * frobenius);
}

TEST(PlasticStrainLaplacian, NullspaceIsTheSixConstantComponentFields) {
  const auto mesh = sinew::testing::make_box_mesh(2, 1, 1);
  const auto laplacian = sinew::offline::make_plastic_strain_laplacian(mesh.tets);
  ASSERT_TRUE(laplacian.ok());
  const Eigen::Index m = mesh.tets.rows();
  const Eigen::MatrixXd psi = sinew::offline::plastic_strain_laplacian_nullspace(m);
  ASSERT_EQ(psi.rows(), 6 * m);
  ASSERT_EQ(psi.cols(), 6);
  EXPECT_LT((psi.transpose() * psi - Eigen::MatrixXd::Identity(6, 6)).norm(), 1e-14);
  for (int i = 0; i < 6; ++i) {
    EXPECT_GT(psi.col(i).norm(), 0.5);
    EXPECT_LT((laplacian.matrix * psi.col(i)).norm(), 1e-14) << "psi_" << i;
    EXPECT_EQ(psi(6 * 3 + i, i), 1.0 / std::sqrt(static_cast<double>(m)));
  }
  // Exactly six zero eigenvalues on a connected mesh (the lemma), the rest clearly positive.
  const Eigen::VectorXd eigenvalues =
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Eigen::MatrixXd(laplacian.matrix))
          .eigenvalues();
  for (int i = 0; i < 6; ++i) EXPECT_LT(std::abs(eigenvalues[i]), 1e-12);
  EXPECT_GT(eigenvalues[6], 1e-3);
}

TEST(PlasticStrainLaplacian, SmallOnSmoothFieldsLargeOnRoughOnes) {
  auto& gen = sinew::testing::rng();
  const auto mesh = sinew::testing::make_box_mesh(3, 3, 3, 1.0 / 3.0);
  const auto laplacian = sinew::offline::make_plastic_strain_laplacian(mesh.tets);
  ASSERT_TRUE(laplacian.ok());
  const Eigen::Index m = mesh.tets.rows();
  // A linear-in-space field (in the tet centroids) around the identity, and a rough field with
  // values of the same range.
  Eigen::Matrix<double, 6, 3> gradient;
  for (int k = 0; k < 6; ++k) gradient.row(k) = sinew::testing::random_vector(3, 0.3, gen);
  Eigen::VectorXd smooth(6 * m), rough(6 * m);
  for (Eigen::Index t = 0; t < m; ++t) {
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (int a = 0; a < 4; ++a)
      centroid += 0.25 * mesh.rest_positions.row(mesh.tets(t, a)).transpose();
    smooth.segment<6>(6 * t) = sinew::offline::identity_plastic_strain() +
                               gradient * (centroid - Eigen::Vector3d::Constant(0.5));
    rough.segment<6>(6 * t) =
        sinew::offline::identity_plastic_strain() + sinew::testing::random_vector(6, 0.15, gen);
  }
  const double smooth_norm = (laplacian.matrix * smooth).norm();
  const double rough_norm = (laplacian.matrix * rough).norm();
  EXPECT_GT(smooth_norm, 0.0);  // the combinatorial Laplacian is not exact on linear fields
  EXPECT_LT(smooth_norm, 0.2 * rough_norm) << "smooth " << smooth_norm << ", rough " << rough_norm;
  // The identity part is in the nullspace: only the variations count.
  const Eigen::VectorXd constant = sinew::offline::identity_plastic_strains(m);
  EXPECT_LT((laplacian.matrix * constant).norm(), 1e-13);
}

}  // namespace
