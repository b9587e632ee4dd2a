#pragma once
/// The beam's centreline between two nodes as a cubic Hermite curve built from the nodal positions
/// and rotations. A straight chord sits up to l²κ/8 off a bent object (1–2 px for the beams we
/// track); the Hermite curve uses the nodal rotations, so it follows constant curvature to O(l⁴κ³).
///
/// Element e runs from node e to node e+1 with reference chord length L₀; T_i is node i's unit
/// reference tangent (shared by both elements at the node, so a curved reference polyline becomes a
/// smooth C¹ curve). At parameter ξ ∈ [0, 1] the point is
///   c(ξ) = h₀₀ x₁ + h₁₀ L₀ R(θ₁) T₁ + h₀₁ x₂ + h₁₁ L₀ R(θ₂) T₂
/// with the cubic Hermite basis h and x_i = X_i + (ux_i, uy_i). It depends on the element's six
/// dofs only, so image terms keep the stiffness block-tridiagonal.

#include <Eigen/Core>

#include "common/beam/beam_element.hpp"

namespace sinew::rt {

struct CentrelinePoint {
  Eigen::Vector2d position;              ///< c(ξ), pixels
  Eigen::Vector2d normal;                ///< unit normal, the tangent turned by +90°
  Eigen::Matrix<double, 2, 6> jacobian;  ///< ∂c/∂u_e for the element's dofs [ux1 uy1 θ1 ux2 uy2 θ2]
};

/// The parts of an element's Hermite curve that do not depend on ξ: its end positions and its end
/// tangents R(θ)·T (two sines and cosines). Evaluated once per element and state, then shared by
/// all of the element's sample points (the per-point work is then a few multiply-adds).
struct HermiteElement {
  double L0 = 0.0;                               ///< reference chord length, pixels
  Eigen::Vector2d D = Eigen::Vector2d::Zero();   ///< unit reference chord direction
  Eigen::Vector2d x1 = Eigen::Vector2d::Zero();  ///< current first end position, pixels
  Eigen::Vector2d x2 = Eigen::Vector2d::Zero();  ///< current second end position, pixels
  Eigen::Vector2d t1 = Eigen::Vector2d::Zero();  ///< current unit end tangent R(θ₁)·T₁
  Eigen::Vector2d t2 = Eigen::Vector2d::Zero();  ///< current unit end tangent R(θ₂)·T₂
};

/// The ξ-independent part of hermite_centreline (same arguments). `previous`, when given, is the
/// element before this one at the same state: its end tangent is this one's start tangent (one
/// sine and cosine per node instead of two). No allocation.
HermiteElement hermite_element(const Eigen::Vector2d& X1,
                               const common::BeamElementReference& reference,
                               const Eigen::Vector2d& T1, const Eigen::Vector2d& T2,
                               const common::Vector6d& u_e,
                               const HermiteElement* previous = nullptr);

/// The cubic Hermite basis at ξ and its ξ-derivative: all that a centreline point takes from ξ.
/// A tracker's sample points keep their ξ, so it evaluates these once, not at every Newton step.
struct HermiteBasis {
  /// c = h00 x₁ + h10 L₀ t₁ + h01 x₂ + h11 L₀ t₂, and ∂c/∂ξ the same with d00, d10, d01, d11.
  double h00 = 0.0, h10 = 0.0, h01 = 0.0, h11 = 0.0;
  double d00 = 0.0, d10 = 0.0, d01 = 0.0, d11 = 0.0;
};

inline HermiteBasis hermite_basis(double xi) {
  const double xi2 = xi * xi, xi3 = xi2 * xi;
  HermiteBasis b;
  b.h00 = 2 * xi3 - 3 * xi2 + 1;
  b.h10 = xi3 - 2 * xi2 + xi;
  b.h01 = -2 * xi3 + 3 * xi2;
  b.h11 = xi3 - xi2;
  b.d00 = 6 * xi2 - 6 * xi;
  b.d10 = 3 * xi2 - 4 * xi + 1;
  b.d01 = -6 * xi2 + 6 * xi;
  b.d11 = 3 * xi2 - 2 * xi;
  return b;
}

/// c(ξ) at the basis of its ξ, pixels. hermite_position, hermite_normal and
/// hermite_rotation_derivatives are hermite_point in parts, for callers that need fewer of them.
inline Eigen::Vector2d hermite_position(const HermiteElement& h, const HermiteBasis& b) {
  const double L0 = h.L0;
  return b.h00 * h.x1 + b.h10 * L0 * h.t1 + b.h01 * h.x2 + b.h11 * L0 * h.t2;
}

/// The unit normal at c(ξ): the tangent turned by +90° (the chord direction D where the tangent
/// vanishes).
inline Eigen::Vector2d hermite_normal(const HermiteElement& h, const HermiteBasis& b) {
  const double L0 = h.L0;
  Eigen::Vector2d tangent = b.d00 * h.x1 + b.d10 * L0 * h.t1 + b.d01 * h.x2 + b.d11 * L0 * h.t2;
  const double norm = tangent.norm();
  tangent = norm > 0 ? Eigen::Vector2d(tangent / norm) : h.D;
  return Eigen::Vector2d(-tangent.y(), tangent.x());
}

/// ∂c/∂θ₁ and ∂c/∂θ₂, the only columns of ∂c/∂u_e that are not multiples of the identity:
/// ∂c/∂u_e = [h00·I, ∂c/∂θ₁, h01·I, ∂c/∂θ₂] (u_e = [ux1 uy1 θ1 ux2 uy2 θ2]).
inline void hermite_rotation_derivatives(const HermiteElement& h, const HermiteBasis& b,
                                         Eigen::Vector2d* dc_dtheta1, Eigen::Vector2d* dc_dtheta2) {
  const double L0 = h.L0;
  const Eigen::Vector2d dt1(-h.t1.y(), h.t1.x()), dt2(-h.t2.y(), h.t2.x());  // ∂t/∂θ
  *dc_dtheta1 = b.h10 * L0 * dt1;
  *dc_dtheta2 = b.h11 * L0 * dt2;
}

/// The centreline point at ξ of an element prepared by hermite_element; without `jacobian` the
/// point's jacobian is left unset. No allocation.
inline CentrelinePoint hermite_point(const HermiteElement& h, double xi, bool jacobian = true) {
  const HermiteBasis b = hermite_basis(xi);
  CentrelinePoint p;
  p.position = hermite_position(h, b);
  p.normal = hermite_normal(h, b);
  if (!jacobian) return p;
  p.jacobian.setZero();
  p.jacobian(0, 0) = p.jacobian(1, 1) = b.h00;
  p.jacobian(0, 3) = p.jacobian(1, 4) = b.h01;
  Eigen::Vector2d dc_dtheta1, dc_dtheta2;
  hermite_rotation_derivatives(h, b, &dc_dtheta1, &dc_dtheta2);
  p.jacobian.col(2) = dc_dtheta1;
  p.jacobian.col(5) = dc_dtheta2;
  return p;
}

/// Evaluates the Hermite centreline of an element at ξ. X1: reference position of the first node;
/// T1, T2: unit reference tangents at its two nodes; u_e: the element's six dofs. No allocation.
CentrelinePoint hermite_centreline(const Eigen::Vector2d& X1,
                                   const common::BeamElementReference& reference,
                                   const Eigen::Vector2d& T1, const Eigen::Vector2d& T2,
                                   const common::Vector6d& u_e, double xi);

/// Unit reference tangents at the nodes of a polyline (2 x n): the mean of the two adjacent chord
/// directions inside, a parabolic end condition (2·D̂ − T of the neighbour) at the ends. A straight
/// polyline gets its own direction everywhere.
Eigen::Matrix2Xd polyline_node_tangents(const Eigen::Matrix2Xd& nodes);

}  // namespace sinew::rt
