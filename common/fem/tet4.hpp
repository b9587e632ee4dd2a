#pragma once
/// Kinematics of the linear (4-node) tetrahedron, seed 002: rest edge matrix Dm = T, its inverse,
/// signed rest volume, shape functions φ_a and their gradients, the deformation gradient
/// F = Ds·Dm⁻¹ and its derivative dF/dx (the vectorised "B" matrix).
///
/// Conventions
///  - Vertex positions of one element are the columns of a 3x4 matrix [x0 x1 x2 x3] (metres).
///  - The 12 element dofs are vertex-major, x = [x0; y0; z0; x1; ...; z3], which is the
///    column-major storage of that 3x4 matrix (Eigen::Map converts between them).
///  - vec(F) is column-major (common/geometry/matrix_vec.hpp): vec(F)[i + 3j] = F(i, j). The slides
///    of seed 002 use row-major vec(F); our dF/dx is their B with rows permuted.

#include <Eigen/Core>
#include <optional>

#include "common/geometry/matrix_vec.hpp"

namespace sinew::common {

using Vector12d = Eigen::Matrix<double, 12, 1>;
using Matrix12d = Eigen::Matrix<double, 12, 12>;
using Matrix3x4d = Eigen::Matrix<double, 3, 4>;
using Matrix4x3d = Eigen::Matrix<double, 4, 3>;
using Matrix9x12d = Eigen::Matrix<double, 9, 12>;

enum class Tet4Status {
  kValid,       ///< positive rest volume, well shaped enough to invert Dm
  kInverted,    ///< negative signed rest volume (vertex order is left-handed); data still filled
  kDegenerate,  ///< (nearly) zero rest volume: Dm is not invertible; data not valid
  kNonFinite,   ///< NaN or infinite coordinates
};

const char* to_string(Tet4Status status);

/// Everything about one tetrahedron that depends only on its rest shape, computed once.
struct Tet4Rest {
  Tet4Status status = Tet4Status::kDegenerate;
  Eigen::Matrix3d Dm = Eigen::Matrix3d::Zero();  ///< [X1−X0, X2−X0, X3−X0], metres (seed 002: T)
  Eigen::Matrix3d Dm_inv = Eigen::Matrix3d::Zero();  ///< Dm⁻¹, 1/metres
  double volume = 0.0;  ///< signed rest volume det(Dm)/6, cubic metres (> 0 when kValid)
  /// Row a is ∇φ_a (1/metres): rows 1..3 are the rows of Dm⁻¹, row 0 is minus their sum
  /// (seed 002: [−1ᵀT⁻¹; T⁻¹]). F = [x0 x1 x2 x3] · shape_gradients.
  Matrix4x3d shape_gradients = Matrix4x3d::Zero();
  /// dF/dx, 9x12: vec(F) = dFdx · x for the 12 element dofs; dFdx(i + 3j, 3a + i) = ∇φ_a(j).
  Matrix9x12d dFdx = Matrix9x12d::Zero();

  bool valid() const { return status == Tet4Status::kValid; }
};

/// Edge matrix [x1−x0, x2−x0, x3−x0] of vertex positions (columns), metres. Serves as Dm at rest
/// and Ds in the current configuration.
Eigen::Matrix3d edge_matrix(const Matrix3x4d& positions);

/// Signed volume det(edge_matrix)/6, cubic metres; positive for right-handed vertex order.
double signed_volume(const Matrix3x4d& positions);

/// Scale-free shape quality 6·V / ℓ_max³ (ℓ_max the longest edge); 1/√2 ≈ 0.707 for the regular
/// tetrahedron, 0 when flat. Used to decide degeneracy.
double shape_quality(const Matrix3x4d& positions);

/// Precomputes Dm, Dm⁻¹, volume, shape gradients and dF/dx of a rest tetrahedron (columns are
/// X0..X3, metres). Degenerate when |shape_quality| ≤ degeneracy_tolerance (default 1e-10, far
/// below any tet a mesher would produce but still invertible in double precision).
Tet4Rest make_tet4_rest(const Matrix3x4d& rest_positions, double degeneracy_tolerance = 1e-10);

/// Shape-function gradients (4x3) from Dm⁻¹: row 0 = −Σ rows of Dm⁻¹, rows 1..3 = Dm⁻¹.
Matrix4x3d shape_gradients_from_Dm_inv(const Eigen::Matrix3d& Dm_inv);

/// dF/dx (9x12, column-major vec(F), vertex-major x) from the shape-function gradients.
Matrix9x12d deformation_gradient_jacobian(const Matrix4x3d& shape_gradients);

/// Deformation gradient F = Ds·Dm⁻¹ (3x3, dimensionless) of current positions (columns x0..x3).
Eigen::Matrix3d deformation_gradient(const Tet4Rest& rest, const Matrix3x4d& positions);

/// Barycentric coordinates (φ0..φ3, sum 1) of a point in the tetrahedron with the given vertices
/// (columns): φ1..3 = Dm⁻¹ (p − X0), φ0 = 1 − φ1 − φ2 − φ3 (seed 002). All in [0, 1] inside.
/// std::nullopt for a degenerate tetrahedron.
std::optional<Eigen::Vector4d> barycentric_coordinates(const Matrix3x4d& vertices,
                                                       const Eigen::Vector3d& point);

/// Barycentric coordinates from precomputed rest data and the rest position X0 of vertex 0.
Eigen::Vector4d barycentric_coordinates(const Tet4Rest& rest, const Eigen::Vector3d& X0,
                                        const Eigen::Vector3d& point);

/// The 12 element dofs of a 3x4 position matrix (vertex-major) and back.
inline Vector12d to_element_dofs(const Matrix3x4d& positions) {
  return Eigen::Map<const Vector12d>(positions.data());
}
inline Matrix3x4d from_element_dofs(const Vector12d& x) {
  return Eigen::Map<const Matrix3x4d>(x.data());
}

}  // namespace sinew::common
