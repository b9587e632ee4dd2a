#pragma once
/// The geometrically nonlinear plane Timoshenko beam element of seed 000 (appendix): two nodes,
/// three dofs per node (ux, uy, θ), one-point Gauss integration at the element midpoint.
///
/// Strains in the geometrically invariant form of seed 000, written with vectors rather
/// than angles. With the reference chord D = X₂ − X₁ (length L₀), the current chord d = D + u₂ − u₁
/// and the mean cross-section rotation θ̄ = (θ₁ + θ₂)/2, let t = R(θ̄)·D/L₀ be the rotated reference
/// tangent and n = R(π/2)·t its normal. Then
///   1 + e = d·t / L₀       (= (L/L₀) cos γ̄, axial strain)
///       γ = d·n / L₀       (= (L/L₀) sin γ̄, shear strain; γ̄ = ψ − θ̄, ψ the chord rotation)
///       κ = (θ₂ − θ₁) / L₀  (curvature change)
/// No chord angle is ever formed, so nothing wraps at ±π: nodal rotations are total rotations and a
/// beam can roll into a full circle (θ_tip = 2π) without special cases.
///
/// Resultants with pre-stress: N = N⁰ + EA·e, V = V⁰ + GA·γ, M = M⁰ + EI·κ.
/// Energy U = L₀ (N⁰e + ½EA e² + V⁰γ + ½GA γ² + M⁰κ + ½EI κ²); internal force p = ∂U/∂u = L₀ Bᵀz
/// (eq. 6, B of A-7 up to the factor L₀); tangent K_T = ∂p/∂u = K_M + K_G (eq. 7).

#include <Eigen/Core>

namespace sinew::common {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

/// Cross-section stiffnesses of one element: axial EA, shear GA (include any shear correction
/// factor in G or A), bending EI. Consistent units, e.g. N, N, N·m² or pixel-based units.
struct BeamSection {
  double EA = 0.0;
  double GA = 0.0;
  double EI = 0.0;
};

/// Stress resultants in the reference configuration (seed 000, A-8). Zero: stress-free reference.
struct BeamPrestress {
  double N0 = 0.0;  ///< axial force
  double V0 = 0.0;  ///< transverse shear force
  double M0 = 0.0;  ///< bending moment
};

/// Reference geometry of one element: X₁ and the chord D = X₂ − X₁ (any direction: curved beams
/// are polylines of elements with different directions and lengths).
struct BeamElementReference {
  Eigen::Vector2d chord = Eigen::Vector2d::Zero();  ///< D = X₂ − X₁
  double length = 0.0;                              ///< L₀ = |D| > 0
};

/// Generalised strains and stress resultants at the element's Gauss point.
struct BeamStrains {
  double e = 0.0;      ///< axial strain
  double gamma = 0.0;  ///< shear strain
  double kappa = 0.0;  ///< curvature change, 1/length
};

struct BeamResultants {
  double N = 0.0;  ///< axial force
  double V = 0.0;  ///< shear force
  double M = 0.0;  ///< bending moment
};

/// Makes the reference of the element from node X1 to node X2.
BeamElementReference make_beam_element_reference(const Eigen::Vector2d& X1,
                                                 const Eigen::Vector2d& X2);

/// Strains for element displacements u = [ux1, uy1, θ1, ux2, uy2, θ2].
BeamStrains beam_strains(const BeamElementReference& ref, const Vector6d& u);

/// The curvature change κ = (θ₂ − θ₁)/L₀ alone: beam_strains(ref, u).kappa without the sine and
/// cosine that e and γ need (the tracker's bending reference force reads only κ).
inline double beam_curvature(const BeamElementReference& ref, const Vector6d& u) {
  return (u[5] - u[2]) * (1.0 / ref.length);
}

/// Resultants N, V, M from strains.
BeamResultants beam_resultants(const BeamSection& section, const BeamPrestress& prestress,
                               const BeamStrains& strains);

/// Strain energy, internal force p (6) and tangent stiffness K_T = K_M + K_G (6x6) of one element.
/// Any output pointer may be null; nothing is allocated.
void evaluate_beam_element(const BeamElementReference& ref, const BeamSection& section,
                           const BeamPrestress& prestress, const Vector6d& u, double* energy,
                           Vector6d* internal_force, Matrix6d* tangent_stiffness);

/// The strain-displacement matrix B (3x6, rows ∂e/∂u, ∂γ/∂u, ∂κ/∂u; seed 000 A-7 divided by L₀).
Eigen::Matrix<double, 3, 6> beam_strain_displacement(const BeamElementReference& ref,
                                                     const Vector6d& u);

}  // namespace sinew::common
