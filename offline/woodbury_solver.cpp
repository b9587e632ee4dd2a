#include "offline/woodbury_solver.hpp"

#include <cblas.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <vector>

namespace sinew::offline {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// C (rows x cols) = A (rows x inner) · B (inner x cols), column-major, through OpenBLAS: the
// capacitance product ẐB⁻¹Ẑᵀ is r x 6m x r (≈1.5e11 flops for 900 rows on 30k tets), where
// OpenBLAS's run-time-dispatched kernels are several times faster than Eigen's portable ones.
void blas_product(const Eigen::Ref<const Eigen::MatrixXd>& A,
                  const Eigen::Ref<const Eigen::MatrixXd>& B, Eigen::Ref<Eigen::MatrixXd> C) {
  cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, static_cast<int>(A.rows()),
              static_cast<int>(B.cols()), static_cast<int>(A.cols()), 1.0, A.data(),
              static_cast<int>(A.outerStride()), B.data(), static_cast<int>(B.outerStride()), 0.0,
              C.data(), static_cast<int>(C.outerStride()));
}

}  // namespace

const char* to_string(WoodburyStatus status) {
  switch (status) {
    case WoodburyStatus::kOk:
      return "ok";
    case WoodburyStatus::kInvalidOptions:
      return "invalid options";
    case WoodburyStatus::kDisconnectedMesh:
      return "tet mesh is not connected (L has a larger nullspace)";
    case WoodburyStatus::kInvalidInput:
      return "invalid input";
    case WoodburyStatus::kFactorisationFailed:
      return "factorisation of the grounded Laplacian failed";
    case WoodburyStatus::kSingularCapacitance:
      return "capacitance matrix singular (H singular)";
    case WoodburyStatus::kNotFactorised:
      return "constraint rows not set";
  }
  return "unknown";
}

std::optional<std::string> WoodburySolverOptions::validate() const {
  if (block_columns < 1) {
    std::ostringstream out;
    out << "block_columns = " << block_columns << " must be >= 1";
    return out.str();
  }
  return std::nullopt;
}

std::optional<std::string> ConjugateGradientOptions::validate() const {
  std::ostringstream out;
  if (max_iterations < 1) {
    out << "max_iterations = " << max_iterations << " must be >= 1";
    return out.str();
  }
  if (!(relative_tolerance > 0.0 && relative_tolerance < 1.0)) {
    out << "relative_tolerance = " << relative_tolerance << " must be in (0, 1)";
    return out.str();
  }
  return std::nullopt;
}

std::optional<WoodburySolver> WoodburySolver::create(const TetAdjacency& adjacency,
                                                     Eigen::Index num_tets,
                                                     const WoodburySolverOptions& options,
                                                     std::string* error) {
  auto fail = [&](const std::string& why) -> std::optional<WoodburySolver> {
    if (error != nullptr) *error = why;
    return std::nullopt;
  };
  if (auto message = options.validate()) return fail("WoodburySolverOptions: " + *message);
  if (!adjacency.ok() || num_tets < 2)
    return fail("Woodbury solver: needs a valid mesh of >= 2 tets");
  if (adjacency.num_components != 1) {
    std::ostringstream out;
    out << "Woodbury solver: the tet mesh has " << adjacency.num_components
        << " face-connected components; the plastic-strain Laplacian needs exactly 1";
    return fail(out.str());
  }
  WoodburySolver solver;
  solver.options_ = options;
  solver.num_tets_ = num_tets;
  solver.grounded_ = SparseCholesky(SparseCholeskyOptions{options.ordering});
  // L^sc without tet 0: SPD on a connected graph (a grounded graph Laplacian).
  const Eigen::SparseMatrix<double> scalar = scalar_tet_laplacian(adjacency, num_tets);
  const Eigen::SparseMatrix<double> grounded = scalar.bottomRightCorner(num_tets - 1, num_tets - 1);
  const Clock::time_point start = Clock::now();
  const SparseCholeskyStatus status = solver.grounded_.compute(grounded);
  solver.factorisation_seconds_ = seconds_since(start);
  if (status != SparseCholeskyStatus::kOk) {
    return fail(std::string("Woodbury solver: grounded Laplacian: ") + to_string(status));
  }
  return solver;
}

void WoodburySolver::scalar_pseudo_inverse(Eigen::MatrixXd& U) {
  // Project onto 1⊥, solve with tet 0 grounded (row 0 of L^sc y = b then holds automatically, since
  // 1ᵀ(L^sc y − b) = 0), project the solution onto 1⊥: exactly L^sc⁺ U.
  const Eigen::Index m = num_tets_;
  U.rowwise() -= U.colwise().mean();
  work_solution_.resize(m - 1, U.cols());
  grounded_.solve(U.bottomRows(m - 1), work_solution_);
  U.row(0).setZero();
  U.bottomRows(m - 1) = work_solution_;
  U.rowwise() -= U.colwise().mean();
}

void WoodburySolver::squared_pseudo_inverse_block(const Eigen::Ref<const Eigen::MatrixXd>& V,
                                                  Eigen::Ref<Eigen::MatrixXd> out) {
  const Eigen::Index m = num_tets_;
  const Eigen::Index k = V.cols();
  // Gather: column j of V (tet-major 6m) becomes 6 columns (one per component) of an m x 6k block.
  work_rhs_.resize(m, 6 * k);
  for (Eigen::Index j = 0; j < k; ++j) {
    for (Eigen::Index t = 0; t < m; ++t) {
      for (int c = 0; c < 6; ++c) work_rhs_(t, 6 * j + c) = V(6 * t + c, j);
    }
  }
  scalar_pseudo_inverse(work_rhs_);
  scalar_pseudo_inverse(work_rhs_);
  const std::array<double, 6>& w = plastic_strain_laplacian_weights();
  for (Eigen::Index j = 0; j < k; ++j) {
    for (Eigen::Index t = 0; t < m; ++t) {
      for (int c = 0; c < 6; ++c) out(6 * t + c, j) = work_rhs_(t, 6 * j + c) / (w[c] * w[c]);
    }
  }
}

WoodburyStatus WoodburySolver::apply_squared_laplacian_pseudo_inverse(
    const Eigen::Ref<const Eigen::MatrixXd>& V, Eigen::Ref<Eigen::MatrixXd> out) {
  if (V.rows() != size() || out.rows() != size() || out.cols() != V.cols()) {
    return WoodburyStatus::kInvalidInput;
  }
  if (!V.allFinite()) return WoodburyStatus::kInvalidInput;
  const Eigen::Index block = options_.block_columns;
  for (Eigen::Index j0 = 0; j0 < V.cols(); j0 += block) {
    const Eigen::Index k = std::min(block, V.cols() - j0);
    squared_pseudo_inverse_block(V.middleCols(j0, k), out.middleCols(j0, k));
  }
  return WoodburyStatus::kOk;
}

WoodburyStatus WoodburySolver::apply_base_inverse(const Eigen::Ref<const Eigen::MatrixXd>& V,
                                                  Eigen::Ref<Eigen::MatrixXd> out) {
  const WoodburyStatus status = apply_squared_laplacian_pseudo_inverse(V, out);
  if (status != WoodburyStatus::kOk) return status;
  // − ΨΨᵀV: Ψᵀ column c sums component c over the tets, divided by √m.
  const double m = static_cast<double>(num_tets_);
  for (Eigen::Index j = 0; j < V.cols(); ++j) {
    Eigen::Matrix<double, 6, 1> component_mean = Eigen::Matrix<double, 6, 1>::Zero();
    for (Eigen::Index t = 0; t < num_tets_; ++t) component_mean += V.col(j).segment<6>(6 * t);
    component_mean /= m;  // ΨΨᵀv per tet is the component mean
    for (Eigen::Index t = 0; t < num_tets_; ++t) out.col(j).segment<6>(6 * t) -= component_mean;
  }
  return WoodburyStatus::kOk;
}

WoodburyStatus WoodburySolver::set_constraint_rows(const Eigen::Ref<const Eigen::MatrixXd>& Z,
                                                   double nullspace_damping) {
  factorised_ = false;
  if (Z.cols() != size() || !Z.allFinite()) return WoodburyStatus::kInvalidInput;
  if (!(nullspace_damping >= 0.0 && std::isfinite(nullspace_damping))) {
    return WoodburyStatus::kInvalidInput;
  }
  nullspace_scale_ = std::sqrt(1.0 + nullspace_damping);
  const Eigen::Index r = Z.rows();
  const Eigen::Index m = num_tets_;
  Z_ = Z;
  // B⁻¹Ẑᵀ = [B⁻¹Zᵀ, B⁻¹Ψ·k] = [B⁻¹Zᵀ, −k·Ψ] (B = −I on the nullspace; k = √(1 + δ)).
  Clock::time_point start = Clock::now();
  Binv_Zhat_t_.resize(size(), r + 6);
  const WoodburyStatus status = apply_base_inverse(Z.transpose(), Binv_Zhat_t_.leftCols(r));
  if (status != WoodburyStatus::kOk) return status;
  Binv_Zhat_t_.rightCols(6).setZero();
  const double inv_sqrt_m = 1.0 / std::sqrt(static_cast<double>(m));
  for (Eigen::Index t = 0; t < m; ++t) {
    for (int c = 0; c < 6; ++c) Binv_Zhat_t_(6 * t + c, r + c) = -nullspace_scale_ * inv_sqrt_m;
  }
  base_solve_seconds_ = seconds_since(start);

  // Capacitance I + ẐB⁻¹Ẑᵀ = I + [Z; kΨᵀ]·B⁻¹Ẑᵀ.
  start = Clock::now();
  Eigen::MatrixXd capacitance = Eigen::MatrixXd::Identity(r + 6, r + 6);
  Eigen::MatrixXd ZY(r, r + 6);
  blas_product(Z_, Binv_Zhat_t_, ZY);
  capacitance.topRows(r) += ZY;
  for (Eigen::Index j = 0; j < r + 6; ++j) {
    Eigen::Matrix<double, 6, 1> sums = Eigen::Matrix<double, 6, 1>::Zero();
    for (Eigen::Index t = 0; t < m; ++t) sums += Binv_Zhat_t_.col(j).segment<6>(6 * t);
    capacitance.block<6, 1>(r, j) += sums * (nullspace_scale_ * inv_sqrt_m);
  }
  capacitance_.compute(capacitance);
  capacitance_seconds_ = seconds_since(start);
  // PartialPivLU does not report singularity: check the pivots' scale instead.
  const Eigen::VectorXd pivots = capacitance_.matrixLU().diagonal().cwiseAbs();
  if (!pivots.allFinite() || pivots.minCoeff() <= 1e-14 * std::max(1.0, pivots.maxCoeff())) {
    return WoodburyStatus::kSingularCapacitance;
  }
  factorised_ = true;
  return WoodburyStatus::kOk;
}

WoodburyStatus WoodburySolver::solve(const Eigen::Ref<const Eigen::VectorXd>& h,
                                     Eigen::Ref<Eigen::VectorXd> y) {
  if (!factorised_) return WoodburyStatus::kNotFactorised;
  if (h.size() != size() || y.size() != size() || !h.allFinite()) {
    return WoodburyStatus::kInvalidInput;
  }
  // y = B⁻¹h − B⁻¹Ẑᵀ C⁻¹ Ẑ B⁻¹h (eq. 14).
  Eigen::VectorXd Binv_h(size());
  const WoodburyStatus status = apply_base_inverse(h, Binv_h);
  if (status != WoodburyStatus::kOk) return status;
  const Eigen::Index r = Z_.rows();
  Eigen::VectorXd Zhat_Binv_h(r + 6);
  Zhat_Binv_h.head(r).noalias() = Z_ * Binv_h;
  Zhat_Binv_h.tail<6>().setZero();
  const double inv_sqrt_m = 1.0 / std::sqrt(static_cast<double>(num_tets_));
  for (Eigen::Index t = 0; t < num_tets_; ++t) {
    Zhat_Binv_h.tail<6>() += Binv_h.segment<6>(6 * t) * (nullspace_scale_ * inv_sqrt_m);
  }
  const Eigen::VectorXd correction = capacitance_.solve(Zhat_Binv_h);
  y = Binv_h;
  y.noalias() -= Binv_Zhat_t_ * correction;
  return y.allFinite() ? WoodburyStatus::kOk : WoodburyStatus::kSingularCapacitance;
}

void apply_gauss_newton_hessian(const Eigen::SparseMatrix<double>& L,
                                const Eigen::Ref<const Eigen::MatrixXd>& Z,
                                const Eigen::Ref<const Eigen::VectorXd>& v,
                                Eigen::Ref<Eigen::VectorXd> out) {
  const Eigen::VectorXd Lv = L * v;
  out.noalias() = L * Lv;
  const Eigen::VectorXd Zv = Z * v;
  out.noalias() += Z.transpose() * Zv;
}

ConjugateGradientSummary conjugate_gradient_solve(const Eigen::SparseMatrix<double>& L,
                                                  const Eigen::Ref<const Eigen::MatrixXd>& Z,
                                                  const Eigen::Ref<const Eigen::VectorXd>& h,
                                                  Eigen::Ref<Eigen::VectorXd> y,
                                                  const ConjugateGradientOptions& options) {
  ConjugateGradientSummary summary;
  const Clock::time_point start = Clock::now();
  y.setZero();
  const double h_norm = h.norm();
  if (options.validate() || h_norm == 0.0 || !std::isfinite(h_norm)) {
    summary.converged = h_norm == 0.0;
    return summary;
  }
  Eigen::VectorXd residual = h;
  Eigen::VectorXd direction = residual;
  Eigen::VectorXd H_direction(h.size());
  double residual_sq = residual.squaredNorm();
  const double target_sq = std::pow(options.relative_tolerance * h_norm, 2);
  while (summary.iterations < options.max_iterations && residual_sq > target_sq) {
    apply_gauss_newton_hessian(L, Z, direction, H_direction);
    const double curvature = direction.dot(H_direction);
    if (!(curvature > 0.0)) break;
    const double step = residual_sq / curvature;
    y += step * direction;
    residual -= step * H_direction;
    const double next_sq = residual.squaredNorm();
    direction = residual + (next_sq / residual_sq) * direction;
    residual_sq = next_sq;
    ++summary.iterations;
  }
  // The true residual (the recursive one drifts in long runs).
  Eigen::VectorXd Hy(h.size());
  apply_gauss_newton_hessian(L, Z, y, Hy);
  summary.relative_residual = (h - Hy).norm() / h_norm;
  summary.converged = summary.relative_residual <= 10.0 * options.relative_tolerance;
  summary.seconds = seconds_since(start);
  return summary;
}

}  // namespace sinew::offline
