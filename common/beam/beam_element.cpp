#include "common/beam/beam_element.hpp"

#include <cmath>

namespace sinew::common {

BeamElementReference make_beam_element_reference(const Eigen::Vector2d& X1,
                                                 const Eigen::Vector2d& X2) {
  BeamElementReference ref;
  ref.chord = X2 - X1;
  ref.length = ref.chord.norm();
  return ref;
}

namespace {

// Kinematic quantities shared by strains, B and the geometric stiffness.
struct Kinematics {
  Eigen::Vector2d d;  // current chord
  Eigen::Vector2d t;  // reference tangent rotated by the mean rotation θ̄
  Eigen::Vector2d n;  // its normal, t rotated by +90°
  double inv_length = 0.0;
};

Kinematics kinematics(const BeamElementReference& ref, const Vector6d& u) {
  Kinematics k;
  k.inv_length = 1.0 / ref.length;
  k.d = ref.chord + Eigen::Vector2d(u[3] - u[0], u[4] - u[1]);
  const double theta_mean = 0.5 * (u[2] + u[5]);
  const double c = std::cos(theta_mean);
  const double s = std::sin(theta_mean);
  const Eigen::Vector2d D = ref.chord * k.inv_length;
  k.t = Eigen::Vector2d(c * D.x() - s * D.y(), s * D.x() + c * D.y());
  k.n = Eigen::Vector2d(-k.t.y(), k.t.x());
  return k;
}

BeamStrains strains_from(const Kinematics& k, const Vector6d& u) {
  BeamStrains h;
  h.e = k.d.dot(k.t) * k.inv_length - 1.0;
  h.gamma = k.d.dot(k.n) * k.inv_length;
  h.kappa = (u[5] - u[2]) * k.inv_length;
  return h;
}

Eigen::Matrix<double, 3, 6> strain_displacement_from(const Kinematics& k, const BeamStrains& h) {
  // ∂t/∂θᵢ = n/2 and ∂n/∂θᵢ = −t/2, so ∂e/∂θᵢ = γ/2 and ∂γ/∂θᵢ = −(1 + e)/2.
  const double L = k.inv_length;
  Eigen::Matrix<double, 3, 6> B;
  B << -k.t.x() * L, -k.t.y() * L, 0.5 * h.gamma, k.t.x() * L, k.t.y() * L, 0.5 * h.gamma,
      -k.n.x() * L, -k.n.y() * L, -0.5 * (1.0 + h.e), k.n.x() * L, k.n.y() * L, -0.5 * (1.0 + h.e),
      0.0, 0.0, -L, 0.0, 0.0, L;
  return B;
}

}  // namespace

BeamStrains beam_strains(const BeamElementReference& ref, const Vector6d& u) {
  return strains_from(kinematics(ref, u), u);
}

BeamResultants beam_resultants(const BeamSection& section, const BeamPrestress& prestress,
                               const BeamStrains& strains) {
  return {prestress.N0 + section.EA * strains.e, prestress.V0 + section.GA * strains.gamma,
          prestress.M0 + section.EI * strains.kappa};
}

Eigen::Matrix<double, 3, 6> beam_strain_displacement(const BeamElementReference& ref,
                                                     const Vector6d& u) {
  const Kinematics k = kinematics(ref, u);
  return strain_displacement_from(k, strains_from(k, u));
}

void evaluate_beam_element(const BeamElementReference& ref, const BeamSection& section,
                           const BeamPrestress& prestress, const Vector6d& u, double* energy,
                           Vector6d* internal_force, Matrix6d* tangent_stiffness) {
  const Kinematics k = kinematics(ref, u);
  const BeamStrains h = strains_from(k, u);
  const BeamResultants z = beam_resultants(section, prestress, h);
  const double L0 = ref.length;

  if (energy) {
    *energy = L0 * (prestress.N0 * h.e + 0.5 * section.EA * h.e * h.e + prestress.V0 * h.gamma +
                    0.5 * section.GA * h.gamma * h.gamma + prestress.M0 * h.kappa +
                    0.5 * section.EI * h.kappa * h.kappa);
  }
  if (!internal_force && !tangent_stiffness) return;

  // B's rows written out (strain_displacement_from): b0 = ∂e/∂u, b1 = ∂γ/∂u; ∂κ/∂u has two
  // entries, ∓1/L₀ at the rotations. Written entry by entry rather than as Eigen products
  // (2026-12-04: 62–69 → 42 ns per element with the tangent; the tracker's Newton steps, its
  // verification and its load fit evaluate some 350 elements a frame).
  const double L = k.inv_length;
  const double b0[6] = {-k.t.x() * L, -k.t.y() * L, 0.5 * h.gamma,
                        k.t.x() * L,  k.t.y() * L,  0.5 * h.gamma};
  const double b1[6] = {-k.n.x() * L, -k.n.y() * L, -0.5 * (1.0 + h.e),
                        k.n.x() * L,  k.n.y() * L,  -0.5 * (1.0 + h.e)};
  if (internal_force) {
    // seed 000, eq. 6 with one-point integration: L₀ Bᵀ (N, V, M).
    for (int i = 0; i < 6; ++i) (*internal_force)[i] = L0 * (b0[i] * z.N + b1[i] * z.V);
    (*internal_force)[2] -= L0 * L * z.M;
    (*internal_force)[5] += L0 * L * z.M;
  }
  if (tangent_stiffness) {
    // Material part K_M = L₀ Bᵀ diag(EA, GA, EI) B, upper triangle.
    Matrix6d& K = *tangent_stiffness;
    const double sa = L0 * section.EA, sg = L0 * section.GA;
    for (int j = 0; j < 6; ++j) {
      const double a = sa * b0[j], g = sg * b1[j];
      for (int i = 0; i <= j; ++i) K(i, j) = a * b0[i] + g * b1[i];
    }
    const double sb = L0 * section.EI * L * L;
    // Geometric part K_G = L₀ (N ∂²e/∂u² + V ∂²γ/∂u²) (eq. 7). Only the (translation, rotation)
    // and (rotation, rotation) blocks are non-zero because e and γ are bilinear in d and (t, n).
    // ∂²e/∂u₂∂θᵢ = n/(2L₀), ∂²γ/∂u₂∂θᵢ = −t/(2L₀); node-1 translations take the opposite sign.
    const Eigen::Vector2d g = L0 * 0.5 * L * (z.N * k.n - z.V * k.t);
    // ∂²e/∂θᵢ∂θⱼ = −(1 + e)/4, ∂²γ/∂θᵢ∂θⱼ = −γ/4.
    const double rr = -0.25 * L0 * (z.N * (1.0 + h.e) + z.V * h.gamma);
    K(2, 2) += sb + rr;
    K(5, 5) += sb + rr;
    K(2, 5) += rr - sb;
    for (int i : {2, 5}) {
      K(0, i) -= g.x();
      K(1, i) -= g.y();
    }
    K(2, 3) += g.x();
    K(2, 4) += g.y();
    K(3, 5) += g.x();
    K(4, 5) += g.y();
    for (int j = 0; j < 6; ++j) {
      for (int i = j + 1; i < 6; ++i) K(i, j) = K(j, i);
    }
  }
}

}  // namespace sinew::common
