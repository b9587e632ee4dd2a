#include "common/material/stable_neo_hookean.hpp"

#include "common/geometry/determinant.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <sstream>

namespace sinew::common {

namespace {

template <int N>
Eigen::Matrix<double, N, N> project_to_psd_impl(const Eigen::Matrix<double, N, N>& A) {
  using Matrix = Eigen::Matrix<double, N, N>;
  const Matrix symmetric = 0.5 * (A + A.transpose());
  const Eigen::SelfAdjointEigenSolver<Matrix> eigen(symmetric);
  if (eigen.info() != Eigen::Success) return A;  // only on NaN input; leave it to the caller
  if (eigen.eigenvalues().minCoeff() >= 0.0) return A;
  const Eigen::Matrix<double, N, 1> clamped = eigen.eigenvalues().cwiseMax(0.0);
  return eigen.eigenvectors() * clamped.asDiagonal() * eigen.eigenvectors().transpose();
}

}  // namespace

std::optional<std::string> StableNeoHookeanParameters::validate() const {
  std::ostringstream s;
  if (!std::isfinite(youngs_modulus) || !(youngs_modulus > 0.0)) {
    s << "youngs_modulus = " << youngs_modulus << " must be finite and > 0";
    return s.str();
  }
  if (!std::isfinite(poisson_ratio) || !(poisson_ratio > -1.0) || !(poisson_ratio < 0.5)) {
    s << "poisson_ratio = " << poisson_ratio << " must be in (-1, 0.5)";
    return s.str();
  }
  return std::nullopt;
}

LameParameters lame_from_young_poisson(double youngs_modulus, double poisson_ratio) {
  const double E = youngs_modulus;
  const double nu = poisson_ratio;
  return {E / (2.0 * (1.0 + nu)), E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))};
}

LameParameters stable_neo_hookean_lame(const LameParameters& linear) {
  // Matching the linearised stress (header comment): 3μ/2 = 2μ_L and λ − 5μ/8 = λ_L.
  return {4.0 / 3.0 * linear.mu, linear.lambda + 5.0 / 6.0 * linear.mu};
}

StableNeoHookean::StableNeoHookean(double mu, double lambda)
    : mu_(mu), lambda_(lambda), alpha_(1.0 + 0.75 * mu / lambda) {
  psi_rest_ = 0.5 * lambda_ * (1.0 - alpha_) * (1.0 - alpha_) - 0.5 * mu_ * std::log(4.0);
}

std::optional<StableNeoHookean> StableNeoHookean::create(
    const StableNeoHookeanParameters& parameters) {
  if (parameters.validate()) return std::nullopt;
  return from_model_lame(stable_neo_hookean_lame(
      lame_from_young_poisson(parameters.youngs_modulus, parameters.poisson_ratio)));
}

std::optional<StableNeoHookean> StableNeoHookean::from_model_lame(const LameParameters& model) {
  if (!std::isfinite(model.mu) || !std::isfinite(model.lambda) || !(model.mu > 0.0) ||
      !(model.lambda > 0.0)) {
    return std::nullopt;
  }
  return StableNeoHookean(model.mu, model.lambda);
}

double StableNeoHookean::psi(const Eigen::Matrix3d& F) const {
  const double I_C = F.squaredNorm();
  const double J = F.determinant();
  return 0.5 * mu_ * (I_C - 3.0) + 0.5 * lambda_ * (J - alpha_) * (J - alpha_) -
         0.5 * mu_ * std::log(I_C + 1.0) - psi_rest_;
}

Eigen::Matrix3d StableNeoHookean::P(const Eigen::Matrix3d& F) const {
  const double I_C = F.squaredNorm();
  const double J = F.determinant();
  return mu_ * (1.0 - 1.0 / (I_C + 1.0)) * F + lambda_ * (J - alpha_) * determinant_gradient(F);
}

Matrix9d StableNeoHookean::dPdF(const Eigen::Matrix3d& F) const {
  const double I_C = F.squaredNorm();
  const double J = F.determinant();
  const Vector9d f = vec(F);
  const Vector9d g = vec(determinant_gradient(F));

  Matrix9d H = (mu_ * (1.0 - 1.0 / (I_C + 1.0))) * Matrix9d::Identity();
  H.noalias() += (2.0 * mu_ / ((I_C + 1.0) * (I_C + 1.0))) * f * f.transpose();
  H.noalias() += lambda_ * g * g.transpose();

  H.noalias() += (lambda_ * (J - alpha_)) * determinant_hessian(F);
  return H;
}

void evaluate_tet_elastic(const StableNeoHookean& material, const Tet4Rest& rest,
                          const Matrix3x4d& positions, double* energy, Vector12d* gradient,
                          Matrix12d* hessian, HessianProjection projection) {
  const double V = std::abs(rest.volume);
  const Eigen::Matrix3d F = deformation_gradient(rest, positions);
  if (energy) *energy = V * material.psi(F);
  // Seed 002 ("Generalized Forces"): ∂E/∂x = V Bᵀ vec(P); differentiating again, V Bᵀ (∂P/∂F) B.
  if (gradient) gradient->noalias() = V * rest.dFdx.transpose() * vec(material.P(F));
  if (hessian) {
    Matrix9d dPdF = material.dPdF(F);
    if (projection == HessianProjection::kProjectDPdF) dPdF = project_to_psd(dPdF);
    const Matrix9x12d dPdF_B = dPdF * rest.dFdx;
    hessian->noalias() = V * rest.dFdx.transpose() * dPdF_B;
    if (projection == HessianProjection::kProjectElement) *hessian = project_to_psd(*hessian);
  }
}

double tet_elastic_energy(const StableNeoHookean& material, const Tet4Rest& rest,
                          const Matrix3x4d& positions) {
  double energy = 0.0;
  evaluate_tet_elastic(material, rest, positions, &energy, nullptr, nullptr);
  return energy;
}

Vector12d tet_elastic_gradient(const StableNeoHookean& material, const Tet4Rest& rest,
                               const Matrix3x4d& positions) {
  Vector12d gradient;
  evaluate_tet_elastic(material, rest, positions, nullptr, &gradient, nullptr);
  return gradient;
}

Matrix12d tet_elastic_hessian(const StableNeoHookean& material, const Tet4Rest& rest,
                              const Matrix3x4d& positions, HessianProjection projection) {
  Matrix12d hessian;
  evaluate_tet_elastic(material, rest, positions, nullptr, nullptr, &hessian, projection);
  return hessian;
}

Matrix9d project_to_psd(const Matrix9d& A) {
  return project_to_psd_impl<9>(A);
}
Matrix12d project_to_psd(const Matrix12d& A) {
  return project_to_psd_impl<12>(A);
}

}  // namespace sinew::common
