#pragma once
/// det F of a 3x3 matrix with its first and second derivatives in the column-major vec convention
/// (common/geometry/matrix_vec.hpp). Used by the stable neo-Hookean material (J = det F) and by the
/// plastic model (V = det Fp · V₀).

#include <Eigen/Core>

#include "common/geometry/matrix_vec.hpp"

namespace sinew::common {

/// Cross-product matrix: cross_matrix(v)·w = v × w.
inline Eigen::Matrix3d cross_matrix(const Eigen::Vector3d& v) {
  Eigen::Matrix3d M;
  M << 0.0, -v.z(), v.y(),  //
      v.z(), 0.0, -v.x(),   //
      -v.y(), v.x(), 0.0;
  return M;
}

/// ∂ det F / ∂F = cof F: its columns are f1×f2, f2×f0, f0×f1 for the columns f_k of F.
/// Valid for singular F too.
inline Eigen::Matrix3d determinant_gradient(const Eigen::Matrix3d& F) {
  Eigen::Matrix3d C;
  C.col(0) = F.col(1).cross(F.col(2));
  C.col(1) = F.col(2).cross(F.col(0));
  C.col(2) = F.col(0).cross(F.col(1));
  return C;
}

/// ∂² det F / ∂F² (9x9): block (a, b) = ∂(column a of cof F)/∂f_b, e.g. ∂(f1×f2)/∂f2 = [f1]×.
inline Matrix9d determinant_hessian(const Eigen::Matrix3d& F) {
  Matrix9d H = Matrix9d::Zero();
  const Eigen::Matrix3d c0 = cross_matrix(F.col(0));
  const Eigen::Matrix3d c1 = cross_matrix(F.col(1));
  const Eigen::Matrix3d c2 = cross_matrix(F.col(2));
  H.block<3, 3>(0, 3) = -c2;
  H.block<3, 3>(0, 6) = c1;
  H.block<3, 3>(3, 0) = c2;
  H.block<3, 3>(3, 6) = -c0;
  H.block<3, 3>(6, 0) = -c1;
  H.block<3, 3>(6, 3) = c0;
  return H;
}

}  // namespace sinew::common
