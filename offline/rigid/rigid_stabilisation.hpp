#pragma once
/// The stabilisation constraints of a free (un-attached) object, seed 003 §3.6 eqs. 19–20: over a
/// set D of material points (the landmark and ICP-marker points, equal weights w = 1/|D|),
///   eq. 19  Σ_j w x_j − Σ_j w X_j = t                                   (centroid)
///   eq. 20  Polar(Σ_j w (x_j − t)(X_j − X̄)ᵀ) = R,   X̄ = Σ_k w X_k       (average rotation)
/// where x_j = A_j x is the deformed and X_j the template position of point j. The elastic energy
/// is invariant under rigid motions, so these six conditions pick one equilibrium out of the
/// six-dimensional family of §3.6 (the Nullspace Lemma).
///
/// Because Σ_j w (X_j − X̄) = 0, eq. 20's argument equals the covariance C(x) = Σ_j w x_j (X_j −
/// X̄)ᵀ for any t; it is linear in x. As constraint functions (six rows, zero when satisfied):
///   g_c(x) = Σ_j w x_j − X̄ − t,
///   g_r(x) = vee(skew(Rᵀ Polar(C(x)))),   vee(A) = [A₂₁, A₀₂, A₁₀],
/// three independent components of eq. 20 (Rᵀ Polar(C) = I there, and its skew part vanishes);
/// their derivatives use the polar-decomposition derivatives of common/geometry (§3.7, appendix E).
///
/// Layout: x is the vertex-major 3n dof vector (metres).

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "common/fem/tet_mesh_elasticity.hpp"
#include "offline/constraints/constraints.hpp"
#include "offline/rigid/rigid_motion.hpp"

namespace sinew::offline {

/// The (R, t) of eqs. 19–20.
struct RigidFrame {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
};

using Vector6d = Eigen::Matrix<double, 6, 1>;
/// Constraint Jacobian: 6 rows (g_c, g_r), 3n columns.
using StabilisationJacobian = Eigen::Matrix<double, 6, Eigen::Dynamic>;

class RigidStabilisation {
 public:
  /// D = points (material points of the mesh whose rest dofs are rest_dofs). std::nullopt (with
  /// error) when fewer than 3 points are given, one lies in a tet that does not exist, or their
  /// template positions are (nearly) collinear (eq. 20 then does not fix a rotation).
  static std::optional<RigidStabilisation> create(
      const common::TetIndices& tets, const Eigen::Ref<const Eigen::VectorXd>& rest_dofs,
      const std::vector<EmbeddedPoint>& points, std::string* error = nullptr);

  /// Σ_j w x_j.
  Eigen::Vector3d centroid(const Eigen::Ref<const Eigen::VectorXd>& x) const;
  /// C(x) = Σ_j w x_j (X_j − X̄)ᵀ.
  Eigen::Matrix3d covariance(const Eigen::Ref<const Eigen::VectorXd>& x) const;
  /// The frame x satisfies: R = Polar(C(x)), t = Σ w x_j − X̄. std::nullopt when det C(x) ≤ 0
  /// (the points are mirrored or flattened; §3.6 excludes that case).
  std::optional<RigidFrame> frame(const Eigen::Ref<const Eigen::VectorXd>& x) const;
  /// [g_c; g_r] at x for the target frame.
  std::optional<Vector6d> residual(const Eigen::Ref<const Eigen::VectorXd>& x,
                                   const RigidFrame& target) const;
  /// ∂[g_c; g_r]/∂x (6 x 3n, zero outside the support dofs). False when det C(x) ≤ 0 or C is
  /// too close to singular for the polar derivatives.
  bool jacobian(const Eigen::Ref<const Eigen::VectorXd>& x, const RigidFrame& target,
                StabilisationJacobian& G) const;
  /// Σ_i λ_i ∂²g_i/∂x² restricted to the support dofs (3s x 3s, s = support_vertices().size(),
  /// rows/columns in the order of support_vertices(), x/y/z per vertex). g_c is linear, so only
  /// λ₃…λ₅ contribute. False as for jacobian().
  bool hessian(const Eigen::Ref<const Eigen::VectorXd>& x, const RigidFrame& target,
               const Vector6d& lambda, Eigen::MatrixXd& H) const;
  /// Moves x rigidly so that it satisfies eqs. 19–20 for target exactly. The elastic energy does
  /// not change (an equilibrium stays one). False when frame(x) fails.
  bool move_to(const RigidFrame& target, Eigen::Ref<Eigen::VectorXd> x) const;
  /// The rigid transform that move_to applies (x ← Q x + d).
  std::optional<RigidTransform> transform_to(const RigidFrame& target,
                                             const Eigen::Ref<const Eigen::VectorXd>& x) const;

  /// The mesh vertices whose dofs D depends on (sorted).
  const std::vector<Eigen::Index>& support_vertices() const { return vertices_; }
  /// X̄ = Σ_k w X_k.
  const Eigen::Vector3d& rest_centroid() const { return rest_centroid_; }
  Eigen::Index num_dofs() const { return num_dofs_; }

 private:
  RigidStabilisation() = default;
  // dC/dvec-free form: C(x) = Σ_v x_v e_vᵀ and centroid = Σ_v a_v x_v over support vertices.
  std::vector<Eigen::Index> vertices_;
  std::vector<double> centroid_weights_;         // a_v
  std::vector<Eigen::Vector3d> moment_weights_;  // e_v
  Eigen::Vector3d rest_centroid_ = Eigen::Vector3d::Zero();
  Eigen::Index num_dofs_ = 0;
};

}  // namespace sinew::offline
