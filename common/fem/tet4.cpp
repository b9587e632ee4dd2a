#include "common/fem/tet4.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>

namespace sinew::common {

const char* to_string(Tet4Status status) {
  switch (status) {
    case Tet4Status::kValid:
      return "valid";
    case Tet4Status::kInverted:
      return "inverted (negative rest volume)";
    case Tet4Status::kDegenerate:
      return "degenerate (zero rest volume)";
    case Tet4Status::kNonFinite:
      return "non-finite coordinates";
  }
  return "unknown";
}

Eigen::Matrix3d edge_matrix(const Matrix3x4d& positions) {
  Eigen::Matrix3d D;
  D.col(0) = positions.col(1) - positions.col(0);
  D.col(1) = positions.col(2) - positions.col(0);
  D.col(2) = positions.col(3) - positions.col(0);
  return D;
}

double signed_volume(const Matrix3x4d& positions) {
  return edge_matrix(positions).determinant() / 6.0;
}

double shape_quality(const Matrix3x4d& positions) {
  double longest_sq = 0.0;
  for (int a = 0; a < 4; ++a) {
    for (int b = a + 1; b < 4; ++b) {
      longest_sq = std::max(longest_sq, (positions.col(a) - positions.col(b)).squaredNorm());
    }
  }
  if (longest_sq == 0.0) return 0.0;
  const double longest = std::sqrt(longest_sq);
  return 6.0 * signed_volume(positions) / (longest * longest * longest);
}

Matrix4x3d shape_gradients_from_Dm_inv(const Eigen::Matrix3d& Dm_inv) {
  Matrix4x3d G;
  G.row(0) = -Dm_inv.colwise().sum();  // ∇φ0 = −∇φ1 − ∇φ2 − ∇φ3 (seed 002: −1ᵀT⁻¹)
  G.bottomRows<3>() = Dm_inv;
  return G;
}

Matrix9x12d deformation_gradient_jacobian(const Matrix4x3d& shape_gradients) {
  // F(i, j) = Σ_a x_a(i) ∇φ_a(j): vec index i + 3j, dof index 3a + i.
  Matrix9x12d B = Matrix9x12d::Zero();
  for (int a = 0; a < 4; ++a) {
    for (int j = 0; j < 3; ++j) {
      for (int i = 0; i < 3; ++i) B(i + 3 * j, 3 * a + i) = shape_gradients(a, j);
    }
  }
  return B;
}

Tet4Rest make_tet4_rest(const Matrix3x4d& rest_positions, double degeneracy_tolerance) {
  Tet4Rest rest;
  if (!rest_positions.allFinite()) {
    rest.status = Tet4Status::kNonFinite;
    return rest;
  }
  rest.Dm = edge_matrix(rest_positions);
  rest.volume = rest.Dm.determinant() / 6.0;
  const double quality = shape_quality(rest_positions);
  if (std::abs(quality) <= degeneracy_tolerance) {
    rest.status = Tet4Status::kDegenerate;
    return rest;
  }
  rest.Dm_inv = rest.Dm.inverse();  // closed-form 3x3 inverse (cofactors / det)
  rest.shape_gradients = shape_gradients_from_Dm_inv(rest.Dm_inv);
  rest.dFdx = deformation_gradient_jacobian(rest.shape_gradients);
  rest.status = rest.volume > 0.0 ? Tet4Status::kValid : Tet4Status::kInverted;
  return rest;
}

Eigen::Matrix3d deformation_gradient(const Tet4Rest& rest, const Matrix3x4d& positions) {
  return edge_matrix(positions) * rest.Dm_inv;
}

Eigen::Vector4d barycentric_coordinates(const Tet4Rest& rest, const Eigen::Vector3d& X0,
                                        const Eigen::Vector3d& point) {
  Eigen::Vector4d phi;
  phi.tail<3>() = rest.Dm_inv * (point - X0);
  phi(0) = 1.0 - phi.tail<3>().sum();
  return phi;
}

std::optional<Eigen::Vector4d> barycentric_coordinates(const Matrix3x4d& vertices,
                                                       const Eigen::Vector3d& point) {
  const Tet4Rest rest = make_tet4_rest(vertices);
  if (rest.status != Tet4Status::kValid && rest.status != Tet4Status::kInverted) {
    return std::nullopt;
  }
  return barycentric_coordinates(rest, vertices.col(0), point);
}

}  // namespace sinew::common
