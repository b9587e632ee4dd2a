#pragma once
/// Rigid motions of a free (un-attached) object, seed 003 §3.6:
///  - the Nullspace Lemma's six vectors ψ_i = [e_i, …, e_i], ψ_{3+i} = [e_i × x_1, …, e_i × x_n]
///    that span the nullspace of the tangent stiffness at a static equilibrium x;
///  - six "pin" dofs (three of one vertex, two of a second, one of a third) whose fixing removes
///    exactly those motions, so that the pinned stiffness is positive definite and CHOLMOD can
///    factorise it (offline/linalg/singular_solver.hpp, the Newton equilibrium of a free object);
///  - the best rigid transform between corresponding point sets (Kabsch / shape matching: the
///    rotation is the polar factor of the weighted cross-covariance, common/geometry).
///
/// Layout: x is the vertex-major 3n dof vector (metres) of common/fem/sparse_assembly.hpp.

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <array>
#include <optional>
#include <vector>

namespace sinew::offline {

/// The six rigid-motion vectors at positions x (3n x 6): columns 0–2 translations, 3–5
/// infinitesimal rotations about the coordinate axes through the origin. With orthonormalise
/// they are replaced by an orthonormal basis of the same span (Householder QR), which is what
/// projections want.
Eigen::Matrix<double, Eigen::Dynamic, 6> rigid_motion_basis(
    const Eigen::Ref<const Eigen::VectorXd>& x, bool orthonormalise = true);

/// Six dof indices that remove the rigid motions when held fixed: all three of vertex a, the two
/// components of vertex b across the direction a→b, and the component of vertex c that a rotation
/// about the line ab moves most. a, b, c are spread out (a farthest from the centroid, b farthest
/// from a, c farthest from the line ab) so the 6x6 restriction of the rigid basis is well
/// conditioned. std::nullopt when the points are (nearly) collinear or fewer than 3.
std::optional<std::array<Eigen::Index, 6>> rigid_pin_dofs(
    const Eigen::Ref<const Eigen::VectorXd>& x);

/// In place: the stored entries of rows and columns `pins` of A become 0, their diagonal entries
/// `diagonal` (which must be stored). The pattern is unchanged, so a CHOLMOD analysis stays valid.
void pin_dofs(Eigen::SparseMatrix<double>& A, const std::array<Eigen::Index, 6>& pins,
              double diagonal);

/// y = Q p + d.
struct RigidTransform {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Vector3d apply(const Eigen::Vector3d& p) const { return rotation * p + translation; }
  /// Applies the transform to every vertex of x (3n) in place.
  void apply_to_dofs(Eigen::Ref<Eigen::VectorXd> x) const;
  /// this ∘ other (other first).
  RigidTransform after(const RigidTransform& other) const;
};

/// The rotation Q (det +1) and translation d minimising Σ_k w_k ‖Q p_k + d − z_k‖² (weights all 1
/// when empty). std::nullopt when the sizes differ, fewer than 3 points are given, a weight is
/// negative or the points are (nearly) collinear, where the rotation is not determined.
std::optional<RigidTransform> fit_rigid_transform(const std::vector<Eigen::Vector3d>& from,
                                                  const std::vector<Eigen::Vector3d>& to,
                                                  const std::vector<double>& weights = {});

}  // namespace sinew::offline
