#pragma once
/// The stable neo-Hookean material of Smith, de Goes & Kim 2018 ("Stable Neo-Hookean Flesh
/// Simulation", ACM TOG 37(2)):
///   ψ(F) = μ/2 (I_C − 3) + λ/2 (J − α)² − μ/2 log(I_C + 1) − ψ₀,
///   I_C = tr(FᵀF), J = det F, α = 1 + 3μ/(4λ),
/// where α makes the rest state stress-free (P(I) = 0) and the constant
/// ψ₀ = λ/2 (1 − α)² − μ/2 log 4 makes it energy-free (ψ(R) = 0 for every rotation R; the paper
/// leaves ψ₀ in, it changes no derivative). ψ is smooth for every F, including inverted (J < 0)
/// and collapsed (F = 0) ones.
///
/// Lamé reparameterisation. μ, λ above are the model's own parameters, not those of linear
/// elasticity. Linearising P at F = I + εG gives
///   P = ε (3μ/2 sym(G) + (λ − 5μ/8) tr(G) I) + O(ε²),
/// so with the user's linear Lamé parameters (μ_L, λ_L from E, ν) the choice
///   μ = 4/3 μ_L,   λ = λ_L + 5/6 μ_L
/// reproduces linear elasticity 2μ_L sym(G) + λ_L tr(G) I at small strains (as in the paper; the
/// unit test checks it). For ν ∈ (−1, 0.5), λ > 0 always (λ = 0 would need ν = −2.5).
///
/// Derivatives use the column-major vec of common/geometry/matrix_vec.hpp: dPdF(a, b) =
/// ∂vec(P)_a / ∂vec(F)_b = ∂²ψ / ∂vec(F)_a ∂vec(F)_b (symmetric 9x9).

#include <Eigen/Core>
#include <optional>
#include <string>

#include "common/fem/tet4.hpp"
#include "common/geometry/matrix_vec.hpp"

namespace sinew::common {

/// The user's material description.
struct StableNeoHookeanParameters {
  /// Young's modulus E, pascals (or any consistent stress unit), finite and > 0. Soft tissue is
  /// roughly 1e3..1e5 Pa.
  double youngs_modulus = 1e4;
  /// Poisson's ratio ν, dimensionless, in (−1, 0.5). Near 0.5 the material is nearly
  /// incompressible: λ grows like 1/(1 − 2ν) and the system gets stiff.
  double poisson_ratio = 0.45;

  /// Empty when valid; otherwise one line naming the field, its value and the constraint.
  std::optional<std::string> validate() const;
};

/// Lamé parameters, pascals.
struct LameParameters {
  double mu = 0.0;      ///< shear modulus μ
  double lambda = 0.0;  ///< first Lamé parameter λ
};

/// Linear-elasticity Lamé parameters: μ = E / (2(1 + ν)), λ = E ν / ((1 + ν)(1 − 2ν)).
LameParameters lame_from_young_poisson(double youngs_modulus, double poisson_ratio);

/// The stable neo-Hookean model parameters that match the given linear Lamé parameters at small
/// strain: μ = 4/3 μ_L, λ = λ_L + 5/6 μ_L (see the header comment).
LameParameters stable_neo_hookean_lame(const LameParameters& linear);

/// How (if at all) an element Hessian is projected to positive semi-definiteness.
enum class HessianProjection {
  kNone,         ///< exact Hessian (indefinite under compression)
  kProjectDPdF,  ///< clamp negative eigenvalues of the 9x9 ∂P/∂F, then V·Bᵀ(∂P/∂F)₊B
  kProjectElement,  ///< clamp negative eigenvalues of the 12x12 element Hessian
};

class StableNeoHookean {
 public:
  /// The material for the user's E, ν; std::nullopt when parameters.validate() reports an error.
  static std::optional<StableNeoHookean> create(const StableNeoHookeanParameters& parameters);

  /// The material from the model's own Lamé parameters (already reparameterised), both finite and
  /// > 0; std::nullopt otherwise.
  static std::optional<StableNeoHookean> from_model_lame(const LameParameters& model);

  double mu() const { return mu_; }          ///< model μ, pascals
  double lambda() const { return lambda_; }  ///< model λ, pascals
  double alpha() const { return alpha_; }    ///< α = 1 + 3μ/(4λ), dimensionless

  /// Energy density ψ(F), pascals (joules per cubic metre). Zero for rotations.
  double psi(const Eigen::Matrix3d& F) const;

  /// First Piola–Kirchhoff stress P = ∂ψ/∂F (3x3, pascals):
  ///   P = μ (1 − 1/(I_C + 1)) F + λ (J − α) ∂J/∂F,  ∂J/∂F = cof F = [f1×f2, f2×f0, f0×f1].
  Eigen::Matrix3d P(const Eigen::Matrix3d& F) const;

  /// ∂P/∂F (9x9, column-major vec, pascals):
  ///   μ (1 − 1/(I_C+1)) I₉ + 2μ/(I_C+1)² f fᵀ + λ g gᵀ + λ (J − α) H_J,
  /// f = vec F, g = vec ∂J/∂F, H_J = ∂²J/∂F² (3x3 blocks of cross-product matrices of columns).
  Matrix9d dPdF(const Eigen::Matrix3d& F) const;

 private:
  StableNeoHookean(double mu, double lambda);

  double mu_ = 0.0;
  double lambda_ = 0.0;
  double alpha_ = 1.0;
  double psi_rest_ = 0.0;  // ψ₀, so that ψ(I) = 0
};

/// Elastic energy V·ψ(F(x)) of one tetrahedron (joules), its gradient V·dFdxᵀ vec(P)
/// (12, newtons) and Hessian V dFdxᵀ (∂P/∂F) dFdx (12x12, newtons per metre) with respect to the
/// 12 vertex-major dofs, at current positions (columns x0..x3, metres). V = |rest.volume|; rest
/// must be valid (or inverted). Any output pointer may be null; nothing is allocated.
void evaluate_tet_elastic(const StableNeoHookean& material, const Tet4Rest& rest,
                          const Matrix3x4d& positions, double* energy, Vector12d* gradient,
                          Matrix12d* hessian,
                          HessianProjection projection = HessianProjection::kNone);

/// Convenience forms of evaluate_tet_elastic.
double tet_elastic_energy(const StableNeoHookean& material, const Tet4Rest& rest,
                          const Matrix3x4d& positions);
Vector12d tet_elastic_gradient(const StableNeoHookean& material, const Tet4Rest& rest,
                               const Matrix3x4d& positions);
Matrix12d tet_elastic_hessian(const StableNeoHookean& material, const Tet4Rest& rest,
                              const Matrix3x4d& positions,
                              HessianProjection projection = HessianProjection::kNone);

/// Nearest positive semi-definite matrix in the Frobenius norm: eigen-decomposition of the
/// symmetric part with negative eigenvalues clamped to zero (fixed-size SelfAdjointEigenSolver).
/// A matrix whose eigenvalues are all ≥ 0 is returned unchanged (bit for bit).
Matrix9d project_to_psd(const Matrix9d& A);
Matrix12d project_to_psd(const Matrix12d& A);

}  // namespace sinew::common
