#include "offline/linalg/woodbury_solver.hpp"

#include "common/timing.hpp"
#include "offline/detail/column_blocks.hpp"
#include "offline/detail/huge_pages.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <vector>

namespace sinew::offline {
namespace {

using Clock = std::chrono::steady_clock;

using common::seconds_since;

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
  std::ostringstream out;
  if (block_columns < 1) {
    out << "block_columns = " << block_columns << " must be >= 1";
    return out.str();
  }
  if (threads < 0) {
    out << "threads = " << threads << " must be >= 0";
    return out.str();
  }
  if (refinement_steps < 0) {
    out << "refinement_steps = " << refinement_steps << " must be >= 0";
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
  if (!(max_seconds >= 0.0)) {
    out << "max_seconds = " << max_seconds << " must be >= 0";
    return out.str();
  }
  if (progress_every < 1) {
    out << "progress_every = " << progress_every << " must be >= 1";
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
  detail::use_reproducible_product_blocking();
  solver.options_ = options;
  solver.num_tets_ = num_tets;
  solver.threads_ = detail::resolve_threads(options.threads);
  solver.work_.resize(static_cast<std::size_t>(solver.threads_));
  solver.grounded_ =
      SparseCholesky(SparseCholeskyOptions{options.ordering, options.cholesky_method});
  // L^sc without tet 0: SPD on a connected graph (a grounded graph Laplacian).
  solver.scalar_laplacian_ = scalar_tet_laplacian(adjacency, num_tets);
  const Eigen::SparseMatrix<double>& scalar = solver.scalar_laplacian_;
  const Eigen::SparseMatrix<double> grounded = scalar.bottomRightCorner(num_tets - 1, num_tets - 1);
  const Clock::time_point start = Clock::now();
  const SparseCholeskyStatus status = solver.grounded_.compute(grounded);
  solver.factorisation_seconds_ = seconds_since(start);
  if (status != SparseCholeskyStatus::kOk) {
    return fail(std::string("Woodbury solver: grounded Laplacian: ") + to_string(status));
  }
  return solver;
}

void WoodburySolver::scalar_pseudo_inverse(Eigen::MatrixXd& U, ThreadWork& work) const {
  // Project onto 1⊥, solve with tet 0 grounded (row 0 of L^sc y = b then holds automatically, since
  // 1ᵀ(L^sc y − b) = 0), project the solution onto 1⊥: exactly L^sc⁺ U.
  const Eigen::Index m = num_tets_;
  U.rowwise() -= U.colwise().mean();
  work.solution.resize(m - 1, U.cols());
  grounded_.solve(U.bottomRows(m - 1), work.solution, work.cholmod);
  U.row(0).setZero();
  U.bottomRows(m - 1) = work.solution;
  U.rowwise() -= U.colwise().mean();
}

void WoodburySolver::component_pseudo_inverse(const Eigen::Ref<const Eigen::MatrixXd>& V,
                                              Eigen::Index first, Eigen::Index k, int times,
                                              ThreadWork& work,
                                              Eigen::Ref<Eigen::MatrixXd> out) const {
  const Eigen::Index m = num_tets_;
  // Gather: column j of V (tet-major 6m) becomes 6 columns (one per component) of an m x 6k block.
  work.rhs.resize(m, 6 * k);
  for (Eigen::Index j = 0; j < k; ++j) {
    const double* column = V.col(first + j).data();
    for (Eigen::Index t = 0; t < m; ++t) {
      for (int c = 0; c < 6; ++c) work.rhs(t, 6 * j + c) = column[6 * t + c];
    }
  }
  for (int i = 0; i < times; ++i) scalar_pseudo_inverse(work.rhs, work);
  const std::array<double, 6>& w = plastic_strain_laplacian_weights();
  std::array<double, 6> scale;
  for (int c = 0; c < 6; ++c) scale[c] = 1.0 / std::pow(w[c], times);
  for (Eigen::Index j = 0; j < k; ++j) {
    double* column = out.col(first + j).data();
    for (Eigen::Index t = 0; t < m; ++t) {
      for (int c = 0; c < 6; ++c) column[6 * t + c] = work.rhs(t, 6 * j + c) * scale[c];
    }
  }
}

void WoodburySolver::component_pseudo_inverse_of_columns(const Eigen::Ref<const Eigen::MatrixXd>& V,
                                                         int times,
                                                         Eigen::Ref<Eigen::MatrixXd> out) {
  // L⁺ = L^sc⁺ ⊗ diag(1/w): each block of columns is independent.
  detail::for_each_column_block(
      V.cols(), options_.block_columns, threads_,
      [&](int thread, Eigen::Index first, Eigen::Index k) {
        component_pseudo_inverse(V, first, k, times, work_[static_cast<std::size_t>(thread)], out);
      });
}

WoodburyStatus WoodburySolver::apply_squared_laplacian_pseudo_inverse(
    const Eigen::Ref<const Eigen::MatrixXd>& V, Eigen::Ref<Eigen::MatrixXd> out) {
  if (V.rows() != size() || out.rows() != size() || out.cols() != V.cols()) {
    return WoodburyStatus::kInvalidInput;
  }
  if (!V.allFinite()) return WoodburyStatus::kInvalidInput;
  component_pseudo_inverse_of_columns(V, 2, out);
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

void WoodburySolver::compute_z_psi() {
  // ZΨ (r x 6): Ψ's column c sums component c over the tets, / √m; column by column
  // (contiguous), not 6-row slices across all columns (a 6m-stride walk).
  const Eigen::Index r = Zt_.cols(), m = num_tets_;
  const double inv_sqrt_m = 1.0 / std::sqrt(static_cast<double>(m));
  Z_psi_.resize(r, 6);
  for (Eigen::Index j = 0; j < r; ++j) {
    Eigen::Matrix<double, 6, 1> sum = Eigen::Matrix<double, 6, 1>::Zero();
    for (Eigen::Index t = 0; t < m; ++t) sum += Zt_.col(j).segment<6>(6 * t);
    Z_psi_.row(j) = inv_sqrt_m * sum.transpose();
  }
}

WoodburyStatus WoodburySolver::set_constraint_rows_transposed(Eigen::MatrixXd Zt, double relative,
                                                              double floor) {
  factorised_ = false;
  held_count_ = 0;
  if (Zt.rows() != size() || !Zt.allFinite()) return WoodburyStatus::kInvalidInput;
  if (!(relative >= 0.0 && std::isfinite(relative)) || !(floor >= 0.0 && std::isfinite(floor))) {
    return WoodburyStatus::kInvalidInput;
  }
  const Eigen::Index r = Zt.cols();
  Zt_ = std::move(Zt);
  compute_z_psi();
  const double delta = (relative * Z_psi_.squaredNorm() + floor * Zt_.squaredNorm()) / 6.0 + 1e-12;
  const double k = std::sqrt(1.0 + delta);
  nullspace_scale_ = k;

  // With Y = L⁺Zᵀ (one Laplacian solve per row of Z, not two: (L²)⁺ = L⁺L⁺ and L⁺ symmetric),
  //   Z B⁻¹ Zᵀ = Z(L²)⁺Zᵀ − ZΨΨᵀZᵀ = YᵀY − (ZΨ)(ZΨ)ᵀ,  Z B⁻¹(kΨ) = −k ZΨ,  kΨᵀB⁻¹kΨ = −k²I,
  // so the capacitance I + ẐB⁻¹Ẑᵀ needs YᵀY (a symmetric rank-6m product); Y's memory is kept
  // for the next call, not its values.
  Clock::time_point start = Clock::now();
  if (Y_.rows() != size() || Y_.cols() != r) {
    Y_ = Eigen::MatrixXd();
    Y_ = options_.huge_pages ? detail::large_matrix(size(), r) : Eigen::MatrixXd(size(), r);
  }
  Eigen::MatrixXd& Y = Y_;
  component_pseudo_inverse_of_columns(Zt_, 1, Y);
  base_solve_seconds_ = seconds_since(start);

  start = Clock::now();
  Eigen::MatrixXd capacitance = Eigen::MatrixXd::Identity(r + 6, r + 6);
  // YᵀY (upper triangle, then mirrored) with Eigen's product at a fixed blocking, not OpenBLAS's
  // dsyrk: dsyrk's kernels are chosen by CPU at run time and round differently on each.
  Eigen::MatrixXd YtY = Eigen::MatrixXd::Zero(r, r);
  YtY.selfadjointView<Eigen::Upper>().rankUpdate(Y.transpose());
  YtY.triangularView<Eigen::StrictlyLower>() = YtY.transpose();
  capacitance.topLeftCorner(r, r) += YtY - Z_psi_ * Z_psi_.transpose();
  capacitance.topRightCorner(r, 6) = -k * Z_psi_;
  capacitance.bottomLeftCorner(6, r) = -k * Z_psi_.transpose();
  capacitance.bottomRightCorner<6, 6>() -= k * k * Eigen::Matrix<double, 6, 6>::Identity();
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

void WoodburySolver::held_base_inverse(const Eigen::Ref<const Eigen::MatrixXd>& V,
                                       Eigen::Index first, Eigen::Index k, ThreadWork& work,
                                       Eigen::Ref<Eigen::MatrixXd> out) const {
  const Eigen::Index m = num_tets_;
  work.rhs.resize(num_free_, 6 * k);
  for (Eigen::Index j = 0; j < k; ++j) {
    const double* column = V.col(first + j).data();
    for (Eigen::Index t = 0; t < m; ++t) {
      const Eigen::Index row = free_index_[static_cast<std::size_t>(t)];
      if (row < 0) continue;
      for (int c = 0; c < 6; ++c) work.rhs(row, 6 * j + c) = column[6 * t + c];
    }
  }
  work.solution.resize(num_free_, 6 * k);
  held_factor_.solve(work.rhs, work.solution, work.cholmod);
  const std::array<double, 6>& w = plastic_strain_laplacian_weights();
  for (Eigen::Index j = 0; j < k; ++j) {
    double* column = out.col(first + j).data();
    for (Eigen::Index t = 0; t < m; ++t) {
      const Eigen::Index row = free_index_[static_cast<std::size_t>(t)];
      for (int c = 0; c < 6; ++c) {
        column[6 * t + c] = row < 0 ? 0.0 : work.solution(row, 6 * j + c) / (w[c] * w[c]);
      }
    }
  }
}

void WoodburySolver::held_base_inverse_of_columns(const Eigen::Ref<const Eigen::MatrixXd>& V,
                                                  Eigen::Ref<Eigen::MatrixXd> out) {
  detail::for_each_column_block(
      V.cols(), options_.block_columns, threads_,
      [&](int thread, Eigen::Index first, Eigen::Index k) {
        held_base_inverse(V, first, k, held_work_[static_cast<std::size_t>(thread)], out);
      });
}

WoodburyStatus WoodburySolver::set_constraint_rows_transposed_holding(
    Eigen::MatrixXd Zt, const std::vector<Eigen::Index>& held, double relative, double floor,
    double penalty) {
  if (held.empty()) return set_constraint_rows_transposed(std::move(Zt), relative, floor);
  factorised_ = false;
  held_count_ = 0;
  const Eigen::Index m = num_tets_;
  if (Zt.rows() != size() || !Zt.allFinite()) return WoodburyStatus::kInvalidInput;
  if (!(relative >= 0.0 && std::isfinite(relative)) || !(floor >= 0.0 && std::isfinite(floor)) ||
      !(penalty >= 0.0 && std::isfinite(penalty))) {
    return WoodburyStatus::kInvalidInput;
  }
  free_index_.assign(static_cast<std::size_t>(m), 0);
  for (Eigen::Index t : held) {
    if (t < 0 || t >= m) return WoodburyStatus::kInvalidInput;
    free_index_[static_cast<std::size_t>(t)] = -1;
  }
  num_free_ = 0;
  for (Eigen::Index& index : free_index_) {
    if (index == 0) index = num_free_++;
  }
  if (num_free_ == 0) return WoodburyStatus::kInvalidInput;
  const Eigen::Index held_count = m - num_free_;
  const Eigen::Index r = Zt.cols();
  Zt_ = std::move(Zt);
  // δ as set_constraint_rows_transposed would compute it with the penalty rows appended.
  compute_z_psi();
  const double penalty_rows = 6.0 * static_cast<double>(held_count) * penalty * penalty;
  const double delta = (relative * (Z_psi_.squaredNorm() + penalty_rows / static_cast<double>(m)) +
                        floor * (Zt_.squaredNorm() + penalty_rows)) /
                           6.0 +
                       1e-12;
  nullspace_scale_ = std::sqrt(1.0 + delta);
  const double root_delta = std::sqrt(delta);
  const double inv_sqrt_m = 1.0 / std::sqrt(static_cast<double>(m));

  // B_F's scalar part [(L^sc)²]_FF (upper triangle), factorised.
  Clock::time_point start = Clock::now();
  const Eigen::SparseMatrix<double> square = scalar_laplacian_ * scalar_laplacian_;
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(static_cast<std::size_t>(square.nonZeros()));
  for (Eigen::Index column = 0; column < square.outerSize(); ++column) {
    const Eigen::Index fc = free_index_[static_cast<std::size_t>(column)];
    if (fc < 0) continue;
    for (Eigen::SparseMatrix<double>::InnerIterator it(square, column); it; ++it) {
      const Eigen::Index fr = free_index_[static_cast<std::size_t>(it.row())];
      if (fr >= 0 && fr <= fc) entries.emplace_back(fr, fc, it.value());
    }
  }
  Eigen::SparseMatrix<double> restricted(num_free_, num_free_);
  restricted.setFromTriplets(entries.begin(), entries.end());
  held_factor_ = SparseCholesky(SparseCholeskyOptions{options_.ordering, options_.cholesky_method});
  if (held_factor_.compute(restricted) != SparseCholeskyStatus::kOk) {
    return WoodburyStatus::kFactorisationFailed;
  }
  held_work_.resize(static_cast<std::size_t>(threads_));

  // V = B_F⁻¹Zᵀ in Y_'s memory, and B_F⁻¹(√δ Ψ).
  if (Y_.rows() != size() || Y_.cols() != r) {
    Y_ = Eigen::MatrixXd();
    Y_ = options_.huge_pages ? detail::large_matrix(size(), r) : Eigen::MatrixXd(size(), r);
  }
  held_base_inverse_of_columns(Zt_, Y_);
  Eigen::MatrixXd Q = Eigen::MatrixXd::Zero(size(), 6);
  for (int c = 0; c < 6; ++c) {
    for (Eigen::Index t = 0; t < m; ++t) Q(6 * t + c, c) = root_delta * inv_sqrt_m;
  }
  psi_solved_.resize(size(), 6);
  held_base_inverse(Q, 0, 6, held_work_.front(), psi_solved_);
  base_solve_seconds_ = seconds_since(start);

  // C = I + ẐV (SPD: I + Ẑ B_F⁻¹ Ẑᵀ restricted to F), symmetrised.
  start = Clock::now();
  Eigen::MatrixXd capacitance = Eigen::MatrixXd::Identity(r + 6, r + 6);
  capacitance.topLeftCorner(r, r).noalias() += Zt_.transpose() * Y_;
  const Eigen::MatrixXd Zt_psi = Zt_.transpose() * psi_solved_;  // r x 6
  capacitance.topRightCorner(r, 6) += Zt_psi;
  capacitance.bottomLeftCorner(6, r) += Zt_psi.transpose();
  capacitance.bottomRightCorner<6, 6>() += Q.transpose() * psi_solved_;
  capacitance = (0.5 * (capacitance + capacitance.transpose())).eval();
  capacitance_.compute(capacitance);
  capacitance_seconds_ = seconds_since(start);
  const Eigen::VectorXd pivots = capacitance_.matrixLU().diagonal().cwiseAbs();
  if (!pivots.allFinite() || pivots.minCoeff() <= 1e-14 * std::max(1.0, pivots.maxCoeff())) {
    return WoodburyStatus::kSingularCapacitance;
  }
  held_count_ = held_count;
  factorised_ = true;
  return WoodburyStatus::kOk;
}

WoodburyStatus WoodburySolver::held_solve_once(const Eigen::Ref<const Eigen::VectorXd>& h,
                                               Eigen::Ref<Eigen::VectorXd> y) {
  // y = u − V C⁻¹ Ẑu,  u = B_F⁻¹h.
  Eigen::MatrixXd u(size(), 1);
  held_base_inverse(h, 0, 1, held_work_.front(), u);
  const Eigen::Index r = Zt_.cols();
  const Eigen::Index m = num_tets_;
  const double root_delta = std::sqrt(nullspace_damping());
  const double inv_sqrt_m = 1.0 / std::sqrt(static_cast<double>(m));
  Eigen::VectorXd Zhat_u(r + 6);
  Zhat_u.head(r).noalias() = Zt_.transpose() * u.col(0);
  Zhat_u.tail<6>().setZero();
  for (Eigen::Index t = 0; t < m; ++t) Zhat_u.tail<6>() += u.col(0).segment<6>(6 * t);
  Zhat_u.tail<6>() *= root_delta * inv_sqrt_m;
  const Eigen::VectorXd c = capacitance_.solve(Zhat_u);
  y = u.col(0);
  y.noalias() -= Y_ * c.head(r);
  y.noalias() -= psi_solved_ * c.tail<6>();
  return y.allFinite() ? WoodburyStatus::kOk : WoodburyStatus::kSingularCapacitance;
}

Eigen::MatrixXd WoodburySolver::release_constraint_rows() {
  factorised_ = false;
  return std::move(Zt_);
}

WoodburyStatus WoodburySolver::solve(const Eigen::Ref<const Eigen::VectorXd>& h,
                                     Eigen::Ref<Eigen::VectorXd> y) {
  if (!factorised_) return WoodburyStatus::kNotFactorised;
  if (h.size() != size() || y.size() != size() || !h.allFinite()) {
    return WoodburyStatus::kInvalidInput;
  }
  const auto once = [&](const Eigen::Ref<const Eigen::VectorXd>& rhs,
                        Eigen::Ref<Eigen::VectorXd> out) {
    return held_count_ > 0 ? held_solve_once(rhs, out) : solve_once(rhs, out);
  };
  WoodburyStatus status = once(h, y);
  if (status != WoodburyStatus::kOk || options_.refinement_steps == 0) return status;
  // Iterative refinement: the residual of the solve, solved again with the same factorisations.
  Eigen::VectorXd residual(size()), Hy(size()), correction(size());
  for (int step = 0; step < options_.refinement_steps; ++step) {
    apply_hessian(y, Hy);
    residual = h - Hy;
    status = once(residual, correction);
    if (status != WoodburyStatus::kOk) return status;
    y += correction;
  }
  return status;
}

void WoodburySolver::apply_hessian(const Eigen::VectorXd& v, Eigen::VectorXd& out) const {
  const Eigen::Index m = num_tets_;
  const std::array<double, 6>& w = plastic_strain_laplacian_weights();
  out.resize(size());
  // L² = (L^sc)² ⊗ diag(w²), one component at a time.
  Eigen::VectorXd component(m), once(m), twice(m);
  for (int c = 0; c < 6; ++c) {
    for (Eigen::Index t = 0; t < m; ++t) component[t] = v[6 * t + c];
    once.noalias() = scalar_laplacian_ * component;
    twice.noalias() = scalar_laplacian_ * once;
    for (Eigen::Index t = 0; t < m; ++t) out[6 * t + c] = w[c] * w[c] * twice[t];
  }
  const Eigen::VectorXd Zv = Zt_.transpose() * v;
  out.noalias() += Zt_ * Zv;
  // δΨΨᵀv: Ψ_c is 1/√m on component c of every tet.
  const double delta = nullspace_damping();
  Eigen::Matrix<double, 6, 1> sum = Eigen::Matrix<double, 6, 1>::Zero();
  for (Eigen::Index t = 0; t < m; ++t) sum += v.segment<6>(6 * t);
  for (Eigen::Index t = 0; t < m; ++t) out.segment<6>(6 * t) += (delta / double(m)) * sum;
  // Held mode: H restricted to the free tets' rows (y is 0 on the held ones).
  if (held_count_ > 0) {
    for (Eigen::Index t = 0; t < m; ++t) {
      if (free_index_[static_cast<std::size_t>(t)] < 0) out.segment<6>(6 * t).setZero();
    }
  }
}

WoodburyStatus WoodburySolver::solve_once(const Eigen::Ref<const Eigen::VectorXd>& h,
                                          Eigen::Ref<Eigen::VectorXd> y) {
  // y = u − B⁻¹Ẑᵀ C⁻¹ Ẑu,  u = B⁻¹h (eq. 14).
  Eigen::VectorXd u(size());
  const WoodburyStatus status = apply_base_inverse(h, u);
  if (status != WoodburyStatus::kOk) return status;
  const Eigen::Index r = Zt_.cols();
  const double k = nullspace_scale_;
  const double inv_sqrt_m = 1.0 / std::sqrt(static_cast<double>(num_tets_));
  Eigen::VectorXd Zhat_u(r + 6);
  Zhat_u.head(r).noalias() = Zt_.transpose() * u;
  Zhat_u.tail<6>().setZero();
  for (Eigen::Index t = 0; t < num_tets_; ++t) Zhat_u.tail<6>() += u.segment<6>(6 * t);
  Zhat_u.tail<6>() *= k * inv_sqrt_m;
  const Eigen::VectorXd c = capacitance_.solve(Zhat_u);
  // B⁻¹Ẑᵀc = (L²)⁺Zᵀc₁ − Ψ(ZΨ)ᵀc₁ − kΨc₂.
  const Eigen::VectorXd Zt_c = Zt_ * c.head(r);
  Eigen::VectorXd correction(size());
  component_pseudo_inverse(Zt_c, 0, 1, 2, work_.front(), correction);
  const Eigen::Matrix<double, 6, 1> nullspace_part =
      (Z_psi_.transpose() * c.head(r) + k * c.tail<6>()) * inv_sqrt_m;
  for (Eigen::Index t = 0; t < num_tets_; ++t) correction.segment<6>(6 * t) -= nullspace_part;
  y = u - correction;
  return y.allFinite() ? WoodburyStatus::kOk : WoodburyStatus::kSingularCapacitance;
}

void apply_gauss_newton_hessian(const Eigen::SparseMatrix<double>& L,
                                const Eigen::Ref<const Eigen::MatrixXd>& Zt,
                                const Eigen::Ref<const Eigen::VectorXd>& v,
                                Eigen::Ref<Eigen::VectorXd> out) {
  const Eigen::VectorXd Lv = L * v;
  out.noalias() = L * Lv;
  const Eigen::VectorXd Zv = Zt.transpose() * v;
  out.noalias() += Zt * Zv;
}

ConjugateGradientSummary conjugate_gradient_solve(const Eigen::SparseMatrix<double>& L,
                                                  const Eigen::Ref<const Eigen::MatrixXd>& Zt,
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
    if (options.max_seconds > 0.0 && summary.iterations % 16 == 0 &&
        seconds_since(start) > options.max_seconds) {
      break;
    }
    if (options.progress && summary.iterations % options.progress_every == 0 &&
        summary.iterations > 0 &&
        !options.progress(summary.iterations, y, std::sqrt(residual_sq) / h_norm)) {
      break;
    }
    apply_gauss_newton_hessian(L, Zt, direction, H_direction);
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
  apply_gauss_newton_hessian(L, Zt, y, Hy);
  summary.relative_residual = (h - Hy).norm() / h_norm;
  summary.converged = summary.relative_residual <= 10.0 * options.relative_tolerance;
  summary.seconds = seconds_since(start);
  return summary;
}

}  // namespace sinew::offline
