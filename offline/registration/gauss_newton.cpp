#include "offline/registration/gauss_newton.hpp"

#include <fmt/core.h>
#include <nlopt.hpp>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <utility>

#include "common/timing.hpp"
#include "offline/plastic/plastic_strain.hpp"
#include "offline/plastic/plastic_strain_laplacian.hpp"
#include "offline/rigid/rigid_motion.hpp"

namespace sinew::offline {
namespace {

using Clock = std::chrono::steady_clock;
constexpr double kInfinity = std::numeric_limits<double>::infinity();

using common::seconds_since;

// Rest positions (#V by 3) from the 3n dof vector.
Eigen::MatrixXd rest_matrix(const PlasticElasticEnergy& energy) {
  const Eigen::VectorXd& dofs = energy.rest_dofs();
  Eigen::MatrixXd V(energy.num_vertices(), 3);
  for (Eigen::Index v = 0; v < V.rows(); ++v) V.row(v) = dofs.segment<3>(3 * v).transpose();
  return V;
}

// Rigid rounds of one (R, t) update: landmarks have fixed correspondences (one Kabsch fit is
// exact), ICP markers alternate closest points and fits.
int rigid_rounds(RegistrationStage stage) {
  return stage == RegistrationStage::kLandmarks ? 1 : 10;
}

// Σ_k (Σ_t v_tk)² / m = ‖Ψᵀv‖² for v of 6m entries (tet-major; Ψ_k = 1/√m on component k).
double constant_part_squared(const Eigen::Ref<const Eigen::VectorXd>& v) {
  const Eigen::Index m = v.size() / 6;
  if (m == 0) return 0.0;
  Eigen::Matrix<double, 6, 1> sum = Eigen::Matrix<double, 6, 1>::Zero();
  for (Eigen::Index t = 0; t < m; ++t) sum += v.segment<6>(6 * t);
  return sum.squaredNorm() / static_cast<double>(m);
}

// The ν ≥ 0 for which ‖(I + νM)⁻¹b‖ = radius (M symmetric positive definite, ‖b‖ > radius > 0),
// by bisection on log ν: that norm falls monotonically from ‖b‖ (ν = 0) towards 0.
double constant_part_damping(const Eigen::Matrix<double, 6, 6>& M,
                             const Eigen::Matrix<double, 6, 1>& b, double radius) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eigen(M);
  const Eigen::Matrix<double, 6, 1> lambda = eigen.eigenvalues().cwiseMax(0.0);
  const Eigen::Matrix<double, 6, 1> c = eigen.eigenvectors().transpose() * b;
  const auto norm_at = [&](double nu) {
    return (c.array() / (1.0 + nu * lambda.array())).matrix().norm();
  };
  double low = 0.0, high = 1.0;
  for (int k = 0; k < 200 && norm_at(high) > radius; ++k) high *= 10.0;
  for (int k = 0; k < 100; ++k) {
    const double mid = low == 0.0 ? high / 1e3 : std::sqrt(low * high);
    (norm_at(mid) > radius ? low : high) = mid;
    if (high <= low * (1.0 + 1e-6)) break;
  }
  return high;
}

// The Jacobian's tangent is the equilibrium's matrix: factorised the same way.
SparseCholeskyOptions tangent_options(const GaussNewtonOptions& options) {
  return SparseCholeskyOptions{options.equilibrium.ordering, options.equilibrium.cholesky_method};
}

// The state of one registration run: the solvers built once, and the current (s, x).
class Registration {
 public:
  Registration(PlasticElasticEnergy energy, const PointConstraints& springs,
               EquilibriumSolver equilibrium, WoodburySolver woodbury,
               Eigen::SparseMatrix<double> laplacian, const RegistrationConstraints& constraints,
               ClosestSurfacePoint* closest_point, const GaussNewtonOptions& options)
      : energy_(std::move(energy)),
        springs_(springs),
        equilibrium_(std::move(equilibrium)),
        woodbury_(std::move(woodbury)),
        laplacian_(std::move(laplacian)),
        tangent_(tangent_options(options)),
        constraints_(constraints),
        closest_point_(closest_point),
        options_(options),
        free_(springs.size() == 0),
        free_tangent_(tangent_options(options)) {
    const Eigen::MatrixXd rest = rest_matrix(energy_);
    diagonal_ = (rest.colwise().maxCoeff() - rest.colwise().minCoeff()).norm();
  }

  Eigen::VectorXd s;
  Eigen::VectorXd x;
  int equilibrium_solves = 0;

  // Solves the equilibrium for plastic state s_trial from x_trial (in/out); true when converged.
  // A free object's equilibrium is then moved to the current rigid frame (eqs. 19–20).
  bool solve_equilibrium(const Eigen::VectorXd& s_trial, Eigen::VectorXd& x_trial) {
    ++equilibrium_solves;
    const EquilibriumSummary summary = equilibrium_.solve(s_trial, x_trial);
    if (!summary.converged()) return false;
    return !free_ || !stabilisation_ || stabilisation_->move_to(frame_, x_trial);
  }

  bool free_object() const { return free_; }
  // GaussNewtonOptions::hold_clamped_tets: the tets whose plastic state direction() holds.
  void set_held_tets(std::vector<Eigen::Index> tets) { held_tets_ = std::move(tets); }
  const std::vector<Eigen::Index>& held_tets() const { return held_tets_; }

  // The ICP markers' weight relative to alpha in the coming iteration (GaussNewtonOptions::
  // icp_weight_ramp).
  void set_icp_weight_scale(double scale) { icp_weight_scale_ = scale; }
  // Whether the ICP markers count point to plane in the coming iteration (GaussNewtonOptions::
  // icp_point_to_plane_iterations).
  void set_icp_point_to_plane(bool on) { icp_point_to_plane_ = on; }

  // Free objects: the stabilisation set D = the material points of the stage's terms (§3.6), and
  // the frame (R, t) that x satisfies now; line-search equilibria keep it.
  bool set_stabilisation(const PointConstraints& terms, const Eigen::VectorXd& at,
                         std::string* why) {
    std::vector<EmbeddedPoint> points;
    for (const PointConstraint& c : terms.constraints()) points.push_back(c.point);
    stabilisation_ = RigidStabilisation::create(energy_.tets(), energy_.rest_dofs(), points, why);
    if (!stabilisation_) return false;
    const std::optional<RigidFrame> frame = stabilisation_->frame(at);
    if (!frame) {
      if (why != nullptr) *why = "the marker points are mirrored or flat in the current shape";
      stabilisation_.reset();
      return false;
    }
    frame_ = *frame;
    return true;
  }

  // Free objects, the (R, t) half of the block-coordinate descent (§3.6): the rigid motion of x
  // that minimises the stage's marker misfit (Kabsch on the correspondences; ICP markers re-find
  // their closest points between fits). The elastic state is unchanged (Π is rigid-invariant).
  void rigid_update(RegistrationStage stage, Eigen::VectorXd& at, int max_rounds) {
    for (int round = 0; round < max_rounds; ++round) {
      auto terms = objective_constraints(stage, at, nullptr);
      if (!terms || terms->size() < 3) return;
      std::vector<Eigen::Vector3d> from, to;
      std::vector<double> weights;
      for (Eigen::Index k = 0; k < terms->size(); ++k) {
        from.push_back(terms->position(k, at));
        to.push_back(terms->constraints()[static_cast<std::size_t>(k)].target);
        weights.push_back(terms->weight(k));
      }
      const std::optional<RigidTransform> fit = fit_rigid_transform(from, to, weights);
      if (!fit) return;
      fit->apply_to_dofs(at);
      const double angle = Eigen::AngleAxisd(fit->rotation).angle();
      if (angle < 1e-12 && fit->translation.norm() < 1e-12 * diagonal_) return;
    }
  }

  // The objective constraints of a stage at positions x (ICP closest points found at x).
  std::optional<PointConstraints> objective_constraints(RegistrationStage stage,
                                                        const Eigen::VectorXd& at,
                                                        std::string* why) {
    std::vector<PointConstraint> list;
    if (options_.beta > 0.0) {
      for (PointConstraint c : constraints_.attachments) {
        c.weight = options_.beta;
        list.push_back(c);
      }
    }
    const bool landmarks =
        stage == RegistrationStage::kLandmarks ||
        (stage == RegistrationStage::kInitialFit && !constraints_.landmarks.empty()) ||
        (stage == RegistrationStage::kIcpMarkers && options_.icp_stage_landmarks);
    const bool icp =
        stage == RegistrationStage::kIcpMarkers ||
        (stage == RegistrationStage::kInitialFit && (constraints_.landmarks.empty() || free_));
    if (landmarks) {
      // In the ICP stage they follow its weight ramp too (icp_stage_landmarks).
      const double scale = stage == RegistrationStage::kIcpMarkers ? icp_weight_scale_ : 1.0;
      for (PointConstraint c : constraints_.landmarks) {
        c.weight *= options_.alpha * scale;
        list.push_back(c);
      }
    }
    if (icp && !constraints_.icp_markers.empty()) {
      closest_point_->update(at);
      for (const Eigen::Vector3d& z : constraints_.icp_markers) {
        PointConstraint c;
        c.kind = ConstraintKind::kIcpMarker;
        c.point = closest_point_->closest(z);
        c.target = z;
        if (icp_point_to_plane_) c.plane_normal = closest_point_->normal(z);
        c.weight = options_.alpha * icp_weight_scale_;
        list.push_back(c);
      }
    }
    ConstraintCheck check;
    auto set = PointConstraints::create(energy_.num_vertices(), energy_.tets(), std::move(list),
                                        common::PatternStorage::kFull, &check);
    if (!set && why != nullptr) *why = "objective constraints: " + check.message();
    return set;
  }

  double objective(const Eigen::VectorXd& s_at, const Eigen::VectorXd& x_at,
                   const PointConstraints& terms) const {
    // ½‖L s‖² as ½ sᵀ(L(Ls))-free sum (GCC's -Wnull-dereference misfires on squaredNorm here).
    const Eigen::VectorXd Ls = laplacian_ * s_at;
    double sum = 0.0;
    for (Eigen::Index i = 0; i < Ls.size(); ++i) sum += Ls[i] * Ls[i];
    return 0.5 * sum + terms.energy(x_at);
  }

  // Marker misfit of a stage at x (fresh closest points for ICP markers): mean and max, metres.
  std::pair<double, double> marker_errors(RegistrationStage stage, const Eigen::VectorXd& at) {
    std::vector<double> errors;
    if (stage == RegistrationStage::kIcpMarkers) {
      closest_point_->update(at);
      for (const Eigen::Vector3d& z : constraints_.icp_markers) {
        const EmbeddedPoint p = closest_point_->closest(z);
        errors.push_back((embedded_position(energy_.tets(), p, at) - z).norm());
      }
    } else {
      const auto& list = stage == RegistrationStage::kLandmarks ? constraints_.landmarks
                                                                : constraints_.attachments;
      for (const PointConstraint& c : list) {
        errors.push_back((embedded_position(energy_.tets(), c.point, at) - c.target).norm());
      }
    }
    if (errors.empty()) return {0.0, 0.0};
    double sum = 0.0, largest = 0.0;
    for (double e : errors) {
      sum += e;
      largest = std::max(largest, e);
    }
    return {sum / static_cast<double>(errors.size()), largest};
  }

  // The Gauss–Newton direction at (s, x) for the objective terms (eqs. 10–14).
  // damping μ ≥ 0: the step of ((1 + μ)L² + ZᵀZ) Δs = −g (GaussNewtonOptions::damped_step_trials).
  bool direction(RegistrationStage stage, const PointConstraints& terms, double damping,
                 Eigen::VectorXd& step, GaussNewtonIteration& record, std::string* why) {
    const double damping_floor =
        stage == RegistrationStage::kAttachments ? options_.attachment_stage_damping_floor : 0.0;
    Clock::time_point start = Clock::now();
    Eigen::MatrixXd storage = woodbury_.release_constraint_rows();
    std::optional<ConstraintJacobian> jacobian =
        free_ ? free_constraint_jacobian(energy_, terms, *stabilisation_, frame_, s, x,
                                         free_tangent_, why, &storage)
              : constraint_jacobian(energy_, springs_, terms, s, x, tangent_, why, &storage);
    storage = Eigen::MatrixXd();  // not reused (the row count changed): free it now
    record.jacobian_seconds = seconds_since(start);
    if (!jacobian) return false;
    // Held tets by penalty rows while their Zᵀ and L⁺Zᵀ columns fit held_penalty_max_bytes,
    // by elimination (WoodburySolver::set_constraint_rows_transposed_holding) above.
    const double penalty_bytes = 2.0 * 8.0 * static_cast<double>(jacobian->Zt.rows()) * 6.0 *
                                 static_cast<double>(held_tets_.size());
    const bool eliminate = !held_tets_.empty() && jacobian->Zt.cols() > 0 &&
                           penalty_bytes > options_.held_penalty_max_bytes;
    record.held_tets = std::max(record.held_tets, static_cast<int>(held_tets_.size()));
    if (eliminate) record.held_by_elimination = true;
    // Held tets: six penalty rows each (residual 0), stiff against the constraints' own rows.
    const double big = held_tets_.empty() ? 0.0 : 1e3 * jacobian->Zt.rowwise().norm().maxCoeff();
    if (!held_tets_.empty() && jacobian->Zt.cols() > 0 && !eliminate) {
      const Eigen::Index r0 = jacobian->Zt.cols();
      const Eigen::Index extra = 6 * static_cast<Eigen::Index>(held_tets_.size());
      Eigen::MatrixXd Zt(jacobian->Zt.rows(), r0 + extra);
      Zt.leftCols(r0) = jacobian->Zt;
      Zt.rightCols(extra).setZero();
      Eigen::VectorXd res(r0 + extra);
      res.head(r0) = jacobian->residual;
      res.tail(extra).setZero();
      for (std::size_t k = 0; k < held_tets_.size(); ++k) {
        for (int i = 0; i < 6; ++i)
          Zt(6 * held_tets_[k] + i, r0 + 6 * static_cast<Eigen::Index>(k) + i) = big;
      }
      jacobian->Zt = std::move(Zt);
      jacobian->residual = std::move(res);
    }

    start = Clock::now();
    // Gradient of eq. 8 at Δs = 0: L²s + Zᵀr.
    const Eigen::VectorXd Ls = laplacian_ * s;
    Eigen::VectorXd gradient = laplacian_ * Ls;
    gradient.noalias() += jacobian->Zt * jacobian->residual;
    // (1 + μ)L² + ZᵀZ = (1 + μ)(L² + Z̃ᵀZ̃) with Z̃ = Z/√(1 + μ): the same Woodbury solve.
    if (damping > 0.0) jacobian->Zt *= 1.0 / std::sqrt(1.0 + damping);
    WoodburyStatus solved =
        eliminate ? woodbury_.set_constraint_rows_transposed_holding(
                        std::move(jacobian->Zt), held_tets_, options_.nullspace_damping,
                        damping_floor, big / std::sqrt(1.0 + damping))
                  : woodbury_.set_constraint_rows_transposed(
                        std::move(jacobian->Zt), options_.nullspace_damping, damping_floor);
    step.resize(s.size());
    if (solved == WoodburyStatus::kOk) solved = woodbury_.solve(-gradient, step);
    double constant_damping = 0.0;  // ν of the constant-strain limit, when it binds
    if (solved == WoodburyStatus::kOk && damping > 0.0 && damping >= options_.rescue_min_damping &&
        options_.constant_strain_step_limit > 0.0)
      solved = limit_constant_part(damping, step, &constant_damping);
    if (damping > 0.0) step /= 1.0 + damping;
    // The (undamped) quadratic model's decrease for the step: −gᵀΔs − ½ΔsᵀHΔs, where
    // HΔs = −g − μL²Δs, so −½gᵀΔs + ½μ‖LΔs‖² (−½gᵀΔs for the plain step).
    record.predicted_decrease = -0.5 * gradient.dot(step);
    if (damping > 0.0) {
      const Eigen::VectorXd Ld = laplacian_ * step;
      record.predicted_decrease += 0.5 * damping * Ld.squaredNorm();
      record.predicted_decrease += 0.5 * constant_damping * constant_part_squared(step);
    }
    record.woodbury_seconds = seconds_since(start);
    if (solved != WoodburyStatus::kOk) {
      *why = std::string("Woodbury solve: ") + to_string(solved);
      return false;
    }
    // The equilibrium's first-order move for the step, dx = K⁻¹(−∂f/∂s Δs) (a free object's
    // K⁺, without the rigid correction that move_to applies anyway): the warm start of the line
    // search's equilibria (predictor_warm_start). One more back-substitution with the factor
    // the Jacobian used; ∂f/∂s is still the one evaluated at (s, x) for it.
    predicted_dx_.resize(0);
    if (options_.predictor_warm_start) {
      const Eigen::VectorXd rhs = -(energy_.force_jacobian() * step);
      Eigen::VectorXd dx(rhs.size());
      bool ok = false;
      if (free_) {
        Eigen::MatrixXd W;
        ok = free_tangent_.solve(rhs, W) == SparseCholeskyStatus::kOk && W.cols() == 1;
        if (ok) dx = W.col(0);
      } else {
        ok = tangent_.solve(rhs, dx) == SparseCholeskyStatus::kOk;
      }
      if (ok && dx.allFinite()) predicted_dx_ = std::move(dx);
    }
    return true;
  }

  // GaussNewtonOptions::constant_strain_step_limit: y solves H̃y = −g (H̃ = L² + Z̃ᵀZ̃ + δΨΨᵀ, the
  // damped system over 1 + μ; the step is y/(1 + μ)). When the step's mean over the tets is longer
  // than the limit, y becomes the solution of (H̃ + ν̃ΨΨᵀ)y = −g with the ν̃ that makes it as long
  // as the limit: y − W(I/ν̃ + ΨᵀW)⁻¹Ψᵀy with W = H̃⁻¹Ψ (six more solves with the same
  // factorisation); *nu = (1 + μ)ν̃, the damping of Ψ in the step's own scale.
  WoodburyStatus limit_constant_part(double damping, Eigen::VectorXd& y, double* nu) {
    const Eigen::Index m = s.size() / 6;
    const double inv_sqrt_m = 1.0 / std::sqrt(static_cast<double>(m));
    Eigen::Matrix<double, 6, 1> mean_s = Eigen::Matrix<double, 6, 1>::Zero();
    Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();  // Ψᵀy
    for (Eigen::Index t = 0; t < m; ++t) {
      mean_s += s.segment<6>(6 * t);
      b += y.segment<6>(6 * t);
    }
    mean_s /= static_cast<double>(m);
    b *= inv_sqrt_m;
    // ‖mean of the step‖ = ‖Ψᵀy‖/((1 + μ)√m) ≤ limit·‖mean of s‖/√(1 + μ).
    const double radius =
        options_.constant_strain_step_limit * mean_s.norm() * std::sqrt(1.0 + damping) / inv_sqrt_m;
    if (!(b.norm() > radius)) return WoodburyStatus::kOk;
    Eigen::MatrixXd W(y.size(), 6);
    Eigen::VectorXd psi = Eigen::VectorXd::Zero(y.size());
    for (int k = 0; k < 6; ++k) {
      for (Eigen::Index t = 0; t < m; ++t) psi[6 * t + k] = inv_sqrt_m;
      const WoodburyStatus status = woodbury_.solve(psi, W.col(k));
      if (status != WoodburyStatus::kOk) return status;
      for (Eigen::Index t = 0; t < m; ++t) psi[6 * t + k] = 0.0;
    }
    Eigen::Matrix<double, 6, 6> M = Eigen::Matrix<double, 6, 6>::Zero();
    for (Eigen::Index t = 0; t < m; ++t) M += W.middleRows(6 * t, 6);
    M *= inv_sqrt_m;
    M = 0.5 * (M + M.transpose()).eval();
    const double scaled = constant_part_damping(M, b, radius);  // ν̃
    const Eigen::Matrix<double, 6, 6> C = Eigen::Matrix<double, 6, 6>::Identity() / scaled + M;
    y.noalias() -= W * C.ldlt().solve(b);
    *nu = (1.0 + damping) * scaled;
    return WoodburyStatus::kOk;
  }

  // Whether no tet of x is inverted relative to its rest orientation: the equilibrium solver
  // keeps tets from inverting only when they are not inverted at its start.
  bool inverts_no_tet(const Eigen::VectorXd& at) const {
    const auto& t = energy_.tets();
    const Eigen::VectorXd& rest = energy_.rest_dofs();
    for (Eigen::Index e = 0; e < t.rows(); ++e) {
      const auto volume = [&](const Eigen::VectorXd& q) {
        const Eigen::Vector3d a = q.segment<3>(3 * t(e, 0));
        return (q.segment<3>(3 * t(e, 1)) - a)
            .cross(q.segment<3>(3 * t(e, 2)) - a)
            .dot(q.segment<3>(3 * t(e, 3)) - a);
      };
      if (volume(at) * volume(rest) <= 0.0) return false;
    }
    return true;
  }

  // dx of the last direction() (empty when none): x + η·dx predicts the equilibrium at s + η·Δs.
  const Eigen::VectorXd& predicted_dx() const { return predicted_dx_; }

  const PlasticElasticEnergy& energy() const { return energy_; }
  const RegistrationConstraints& constraints() const { return constraints_; }
  const Eigen::SparseMatrix<double>& laplacian() const { return laplacian_; }

 private:
  PlasticElasticEnergy energy_;
  // The attachment springs; the equilibrium solver keeps a pointer to the same object.
  const PointConstraints& springs_;
  EquilibriumSolver equilibrium_;
  WoodburySolver woodbury_;
  Eigen::SparseMatrix<double> laplacian_;
  SparseCholesky tangent_;
  const RegistrationConstraints& constraints_;
  ClosestSurfacePoint* closest_point_;
  GaussNewtonOptions options_;
  // Free objects (no springs): the pinned tangent, the stabilisation and its frame.
  bool free_ = false;
  RigidNullspaceSolver free_tangent_;
  std::optional<RigidStabilisation> stabilisation_;
  RigidFrame frame_;
  std::vector<Eigen::Index> held_tets_;  // tets whose s the next direction() keeps
  double diagonal_ = 1.0;  // of the template's bounding box: the scale of "no rigid motion left"
  double icp_weight_scale_ = 1.0;
  bool icp_point_to_plane_ = false;
  Eigen::VectorXd predicted_dx_;
};

// NLopt's C callback for the constant-s fit.
struct ConstantFitData {
  Registration* registration;
  RegistrationStage stage;
  Eigen::VectorXd best_x;
  double best_value = kInfinity;
  Eigen::Matrix<double, 6, 1> best_a;
  int evaluations = 0;
};

// Fp(a)·X for every rest vertex X, moved by the rigid motion that takes Fp(a_pose)·X to
// x_pose (the pose of a shape of the same family; identity when that fit is undetermined).
Eigen::VectorXd uniform_strain_equilibrium(const Eigen::VectorXd& rest,
                                           const Eigen::Matrix<double, 6, 1>& a,
                                           const Eigen::Matrix<double, 6, 1>& a_pose,
                                           const Eigen::VectorXd& x_pose) {
  const Eigen::Index n = rest.size() / 3;
  const Eigen::Matrix3d Fp = plastic_strain_matrix(a);
  const Eigen::Matrix3d Fp_pose = plastic_strain_matrix(a_pose);
  std::vector<Eigen::Vector3d> from, to;
  from.reserve(static_cast<std::size_t>(n));
  to.reserve(static_cast<std::size_t>(n));
  for (Eigen::Index v = 0; v < n; ++v) {
    from.push_back(Fp_pose * rest.segment<3>(3 * v));
    to.push_back(x_pose.segment<3>(3 * v));
  }
  const RigidTransform pose = fit_rigid_transform(from, to).value_or(RigidTransform{});
  Eigen::VectorXd x(rest.size());
  for (Eigen::Index v = 0; v < n; ++v)
    x.segment<3>(3 * v) = pose.apply(Fp * rest.segment<3>(3 * v));
  return x;
}

double constant_fit_objective(unsigned n, const double* a, double* /*gradient*/, void* data) {
  auto* fit = static_cast<ConstantFitData*>(data);
  Registration& r = *fit->registration;
  ++fit->evaluations;
  const Eigen::Map<const Eigen::Matrix<double, 6, 1>> a6(a, n);
  const Eigen::Index m = r.energy().num_tets();
  Eigen::VectorXd s_trial(6 * m);
  for (Eigen::Index t = 0; t < m; ++t) s_trial.segment<6>(6 * t) = a6;
  if (clamp_plastic_state_eigenvalues(s_trial).clamped_tets > 0) return 1e300;
  Eigen::VectorXd x_trial = fit->best_x;
  // A free object under one uniform Fp has the stress-free equilibrium x = Fp·X (Fe = I) up to a
  // rigid motion: start there, in the rigid pose of the best shape so far (best_x is such a shape
  // too), and the Newton solve only confirms it. The attached case has no closed form.
  if (r.free_object())
    x_trial = uniform_strain_equilibrium(r.energy().rest_dofs(), a6, fit->best_a, fit->best_x);
  if (!r.solve_equilibrium(s_trial, x_trial)) return 1e300;
  // A free object takes its best rigid pose for this shape (block-coordinate descent, §3.6).
  if (r.free_object()) r.rigid_update(fit->stage, x_trial, rigid_rounds(fit->stage));
  // Fresh closest points: this is the true ICP distance for the constant strain.
  auto terms = r.objective_constraints(fit->stage, x_trial, nullptr);
  if (!terms) return 1e300;
  const double value = r.objective(s_trial, x_trial, *terms);
  if (std::isfinite(value) && value < fit->best_value) {
    fit->best_value = value;
    fit->best_x = x_trial;
    fit->best_a = a6;
  }
  return std::isfinite(value) ? value : 1e300;
}

}  // namespace

namespace {

// The inputs run_registration cannot use, as its message; std::nullopt when all are usable.
std::optional<std::string> invalid_registration_input(const PlasticElasticEnergy& energy_in,
                                                      const RegistrationConstraints& constraints,
                                                      const ClosestSurfacePoint* closest_point,
                                                      const GaussNewtonOptions& options,
                                                      const GaussNewtonCheckpoint* resume,
                                                      bool free) {
  if (auto message = options.validate()) {
    return "GaussNewtonOptions: " + *message;
  }
  if (!free && constraints.attachments.empty()) {
    return "no attachments: an attached object needs attachments (use register_free for "
           "un-attached objects)";
  }
  if (free && !constraints.attachments.empty()) {
    return "attachments given to register_free: use register_attached";
  }
  if (free && constraints.landmarks.size() < 3 && constraints.icp_markers.size() < 3) {
    return "a free object needs at least 3 landmarks or 3 ICP markers to fix its rigid "
           "motion (eqs. 19-20)";
  }
  if (!constraints.icp_markers.empty() && closest_point == nullptr) {
    return "ICP markers given without a closest-point "
           "structure";
  }
  if (resume != nullptr) {
    if (resume->free_object != free) {
      return std::string("checkpoint: written by ") +
             (resume->free_object ? "register_free" : "register_attached") + ", resumed by " +
             (free ? "register_free" : "register_attached");
    }
    if (resume->s.size() != 6 * energy_in.num_tets() ||
        resume->x.size() != 3 * energy_in.num_vertices()) {
      return "checkpoint: s has " + std::to_string(resume->s.size()) + " and x " +
             std::to_string(resume->x.size()) + " entries, the mesh needs " +
             std::to_string(6 * energy_in.num_tets()) + " and " +
             std::to_string(3 * energy_in.num_vertices());
    }
    if (!resume->s.allFinite() || !resume->x.allFinite() || resume->next_iteration < 1) {
      return "checkpoint: non-finite state or next_iteration < 1";
    }
  }
  return std::nullopt;
}

// A checkpoint's state taken up: where to go on (the stage index, stages.size() when all are done,
// and its iteration), the state and the iterations so far. False (error set) when the checkpoint
// names a stage this registration does not run.
bool resume_state(const GaussNewtonCheckpoint& resume, const std::vector<RegistrationStage>& stages,
                  Registration& r, GaussNewtonSummary& summary, std::size_t* first_stage,
                  int* first_iteration, std::string* error) {
  *first_stage = stages.size();
  if (resume.next_stage) {
    const auto at = std::find(stages.begin(), stages.end(), *resume.next_stage);
    if (at == stages.end()) {
      *error = std::string("checkpoint: stage '") + to_string(*resume.next_stage) +
               "' is not a stage of this registration";
      return false;
    }
    *first_stage = static_cast<std::size_t>(at - stages.begin());
    *first_iteration = resume.next_iteration;
  }
  r.s = resume.s;
  r.x = resume.x;
  r.equilibrium_solves = resume.equilibrium_solves;
  summary.iterations = resume.iterations;
  summary.initial_objective = resume.initial_objective;
  return true;
}

// §3.6: a free object starts from a rigid alignment of the template to the scan (landmark
// correspondences, or centroids and ICP), so that any pose of the scan frame works.
void align_free_object(Registration& r, const PlasticElasticEnergy& energy_in,
                       const RegistrationConstraints& constraints) {
  if (constraints.landmarks.size() >= 3) {
    std::vector<Eigen::Vector3d> from, to;
    for (const PointConstraint& c : constraints.landmarks) {
      from.push_back(embedded_position(energy_in.tets(), c.point, r.x));
      to.push_back(c.target);
    }
    if (const auto fit = fit_rigid_transform(from, to)) fit->apply_to_dofs(r.x);
  } else {
    Eigen::Vector3d markers = Eigen::Vector3d::Zero(), vertices = Eigen::Vector3d::Zero();
    for (const Eigen::Vector3d& z : constraints.icp_markers) markers += z;
    markers /= static_cast<double>(constraints.icp_markers.size());
    for (Eigen::Index v = 0; v < r.x.size() / 3; ++v) vertices += r.x.segment<3>(3 * v);
    vertices /= static_cast<double>(r.x.size() / 3);
    RigidTransform{Eigen::Matrix3d::Identity(), markers - vertices}.apply_to_dofs(r.x);
    r.rigid_update(RegistrationStage::kIcpMarkers, r.x, 50);
  }
}

// The springs pull the template to the attachment targets first. When the targets are far (a
// twisted bar, a bone in another pose) the direct solve may fail: then it is retried allowing
// inverted tets on the way, directly and, failing that, with the targets moved from where the
// template has its attachment points to where they belong in first_equilibrium_steps equal steps.
// Whether an equilibrium was reached.
bool first_attached_equilibrium(Registration& r, PointConstraints& springs,
                                EquilibriumSolver& first_equilibrium,
                                const PlasticElasticEnergy& energy_in,
                                const RegistrationConstraints& constraints,
                                const GaussNewtonOptions& options) {
  const Eigen::VectorXd s0 = r.s;
  r.x = energy_in.rest_dofs();
  ++r.equilibrium_solves;
  bool reached = first_equilibrium.solve(s0, r.x).converged();
  const auto& list = constraints.attachments;
  for (int step_index = 1; !reached && step_index <= options.first_equilibrium_steps;
       ++step_index) {
    if (step_index == 1) r.x = energy_in.rest_dofs();
    const double t = static_cast<double>(step_index) / options.first_equilibrium_steps;
    for (std::size_t i = 0; i < list.size(); ++i) {
      const Eigen::Vector3d start =
          embedded_position(energy_in.tets(), list[i].point, energy_in.rest_dofs());
      // The last step sets the targets exactly (start + 1·(target − start) may differ from
      // target in the last bit), so that the springs hold no trace of the continuation and a
      // resumed run, which skips it, solves the same equilibria.
      springs.set_target(static_cast<Eigen::Index>(i),
                         step_index == options.first_equilibrium_steps
                             ? list[i].target
                             : Eigen::Vector3d(start + t * (list[i].target - start)));
    }
    ++r.equilibrium_solves;
    const bool step_reached = first_equilibrium.solve(s0, r.x).converged();
    if (!step_reached) break;
    reached = step_index == options.first_equilibrium_steps;
  }
  return reached;
}

// §3.4 "Initial guess": one constant s for all tets (NLopt BOBYQA over its 6 entries), recorded
// as the run's first iteration. False (error set) when the objective cannot be formed.
bool initial_constant_fit(Registration& r, bool free, RegistrationStage final_stage,
                          const GaussNewtonOptions& options, GaussNewtonSummary& summary,
                          const GaussNewtonProgress& progress, std::string& error) {
  const Clock::time_point start = Clock::now();
  const int solves_before = r.equilibrium_solves;
  ConstantFitData fit{&r,        RegistrationStage::kInitialFit, r.x,
                      kInfinity, identity_plastic_strain(),      0};
  if (free) {
    auto terms = r.objective_constraints(RegistrationStage::kInitialFit, r.x, &error);
    if (!terms || !r.set_stabilisation(*terms, r.x, &error)) {
      return false;
    }
  }
  std::vector<double> a(6);
  for (int i = 0; i < 6; ++i) a[static_cast<std::size_t>(i)] = identity_plastic_strain()[i];
  const double start_value = constant_fit_objective(6, a.data(), nullptr, &fit);
  nlopt::opt optimiser(nlopt::LN_BOBYQA, 6);
  std::vector<double> lower(6), upper(6);
  for (int i = 0; i < 6; ++i) {
    const bool diagonal = !is_off_diagonal_component(i);
    lower[static_cast<std::size_t>(i)] = diagonal ? 0.05 : -5.0;
    upper[static_cast<std::size_t>(i)] = diagonal ? 20.0 : 5.0;
  }
  optimiser.set_lower_bounds(lower);
  optimiser.set_upper_bounds(upper);
  optimiser.set_min_objective(constant_fit_objective, &fit);
  optimiser.set_maxeval(options.initial_fit_evaluations);
  optimiser.set_ftol_rel(1e-5);
  optimiser.set_initial_step(0.05);
  double value = 0.0;
  try {
    optimiser.optimize(a, value);
  } catch (const std::exception&) {
    // NLopt reports round-off limits and forced stops by exceptions; the best point is kept.
  }
  GaussNewtonIteration record;
  record.stage = RegistrationStage::kInitialFit;
  record.iteration = 1;
  record.objective_before = start_value;
  record.objective = start_value;
  if (fit.best_value < start_value) {
    for (Eigen::Index t = 0; t < r.energy().num_tets(); ++t) r.s.segment<6>(6 * t) = fit.best_a;
    r.x = fit.best_x;
    record.objective = fit.best_value;
    record.step = 1.0;
  }
  std::tie(record.marker_error_mean, record.marker_error_max) = r.marker_errors(final_stage, r.x);
  record.equilibrium_solves = r.equilibrium_solves - solves_before;
  record.seconds = seconds_since(start);
  summary.iterations.push_back(record);
  if (progress) progress(record);
  return true;
}

// The line search of one Gauss–Newton iteration (§3.4): Φ at the static equilibrium of s + η·step
// (or, projected, of clamp(s + η·direction)), keeping the best state of every evaluation.
struct LineSearch {
  LineSearch(Registration& registration, const GaussNewtonOptions& run_options,
             const PointConstraints& objective_terms, Eigen::VectorXd& gauss_newton_step,
             double before)
      : r(registration),
        options(run_options),
        terms(objective_terms),
        step(gauss_newton_step),
        best_s(registration.s),
        best_value(before),
        best_x(registration.x) {}

  void state_at(double eta, Eigen::VectorXd& s_eta) const {
    if (!projected) {
      s_eta = r.s + eta * step;
      return;
    }
    s_eta = r.s + eta * direction;
    clamp_plastic_state_eigenvalues(s_eta, options.eigenvalue_floor);
  }

  double phi(double eta) {
    Eigen::VectorXd s_trial;
    state_at(eta, s_trial);
    Eigen::VectorXd x_trial = r.x;
    // Warm start at the linear prediction of the equilibrium (predictor_warm_start); from x
    // itself when there is none or it fails.
    bool solved = false;
    Eigen::VectorXd inverted;  // the predicted start's equilibrium when it inverts a tet
    bool scored_inverted = false;
    if (!projected && trial_dx.size() == x_trial.size()) {
      x_trial.noalias() += eta * trial_dx;
      // The prediction may invert tets, which the solver then need not undo (it only keeps
      // tets that start uninverted so): an equilibrium with an inverted tet is solved again
      // from x. Starting from x alone instead stalled sub-verse023 (34 s per iteration).
      const bool converged = r.solve_equilibrium(s_trial, x_trial);
      solved = converged && r.inverts_no_tet(x_trial);
      if (converged && !solved && options.inverted_equilibrium_fallback) inverted = x_trial;
      if (!solved) x_trial = r.x;
    }
    // A failed equilibrium scores "+∞", growing with η so that Brent retreats towards 0. With
    // inverted_equilibrium_fallback the inverted equilibrium is scored instead on a direction
    // damped at μ ≥ rescue_min_damping; on a less damped one it is only kept aside (the search
    // is unchanged) and take_inverted() uses it when no trial lowered Φ.
    if (!solved && !r.solve_equilibrium(s_trial, x_trial)) {
      if (inverted.size() == 0) return 1e300 * (1.0 + eta);
      if (trial_damping < options.rescue_min_damping) {
        const double value = r.objective(s_trial, inverted, terms);
        if (value < inverted_value) {
          inverted_value = value;
          inverted_eta = eta;
          inverted_x = std::move(inverted);
          inverted_s = s_trial;
          inverted_projected = projected;
        }
        return 1e300 * (1.0 + eta);
      }
      x_trial = std::move(inverted);
      scored_inverted = true;
    }
    const double value = r.objective(s_trial, x_trial, terms);
    if (value < best_value) {
      best_value = value;
      best_eta = eta;
      best_x = x_trial;
      best_s = s_trial;
      best_projected = projected;
      best_inverted = scored_inverted;
    }
    return value;
  }

  // GaussNewtonOptions::inverted_equilibrium_fallback: when no trial lowered Φ, the best trial
  // whose only equilibrium inverts a tet, if it lowered Φ. True when the step taken ends at an
  // inverted equilibrium (this one, or one scored on a direction damped at μ ≥
  // rescue_min_damping).
  bool take_inverted() {
    if (!take_deferred_inverted_trial(best_eta, best_value, inverted_value))
      return best_eta > 0.0 && best_inverted;
    best_value = inverted_value;
    best_eta = inverted_eta;
    best_x = std::move(inverted_x);
    best_s = std::move(inverted_s);
    best_projected = inverted_projected;
    return true;
  }

  // Brent's search of [0, max_step] (§3.4).
  void search() {
    brent_minimise([this](double eta) { return phi(eta); }, 0.0, options.max_step,
                   options.line_search_tolerance, options.line_search_evaluations - 1);
  }

  Registration& r;
  const GaussNewtonOptions& options;
  const PointConstraints& terms;
  Eigen::VectorXd& step;
  Eigen::VectorXd direction, best_s;
  bool projected = false, best_projected = false;
  double best_value;
  double best_eta = 0.0;
  Eigen::VectorXd best_x;
  Eigen::VectorXd trial_dx;    // the equilibrium's predicted move for the trial's step
  double trial_damping = 0.0;  // μ of the trial's direction
  // The best trial whose equilibrium inverts a tet (inverted_equilibrium_fallback).
  double inverted_value = kInfinity;
  double inverted_eta = 0.0;
  bool inverted_projected = false;
  Eigen::VectorXd inverted_x, inverted_s;
  bool best_inverted = false;  // the best state is an inverted equilibrium
};

// The step of one iteration: the Gauss–Newton direction, with the tets whose eigenvalues it would
// clamp held (hold_clamped_tets), its full step evaluated on the line search, and more damped
// directions while the full step does not achieve full_step_acceptance of the model's decrease
// (damped_step_trials). False (error set) when a linear solve fails; *full_step_good when a full
// step is taken.
bool damped_step_trials(LineSearch& ls, RegistrationStage stage, double before, bool ramping,
                        double damping, GaussNewtonIteration& record, bool* full_step_good,
                        Clock::time_point* search_start, std::string& error) {
  Registration& r = ls.r;
  const GaussNewtonOptions& options = ls.options;
  Eigen::VectorXd& step = ls.step;
  r.set_held_tets({});
  for (int trial = 0;; ++trial) {
    if (!r.direction(stage, ls.terms, damping, step, record, &error)) return false;
    // §3.4: keep Fp positive definite (eigenvalues ≥ floor), then search along the result.
    // When that search finds no decrease and tets were clamped, the projected path
    // s(η) = clamp(s + η·d) is searched as well (GaussNewtonOptions::
    // projected_search_fallback).
    Eigen::VectorXd target = r.s + step;
    record.clamped_tets = static_cast<int>(
        clamp_plastic_state_eigenvalues(target, options.eigenvalue_floor).clamped_tets);
    if (record.clamped_tets > 0 && options.hold_clamped_tets && !ramping) {
      // The clamped tets join the held ones (for this iteration's further trials too), and
      // the step is solved again (GaussNewtonOptions::hold_clamped_tets).
      std::vector<Eigen::Index> held = r.held_tets();
      const Eigen::VectorXd unclamped = r.s + step;
      for (Eigen::Index t = 0; t < r.energy().num_tets(); ++t) {
        if (target.segment<6>(6 * t) != unclamped.segment<6>(6 * t) &&
            std::find(held.begin(), held.end(), t) == held.end())
          held.push_back(t);
      }
      r.set_held_tets(std::move(held));
      if (!r.direction(stage, ls.terms, damping, step, record, &error)) return false;
      target = r.s + step;
      record.clamped_tets = static_cast<int>(
          clamp_plastic_state_eigenvalues(target, options.eigenvalue_floor).clamped_tets);
    }
    record.damping = damping;
    ls.trial_damping = damping;
    ls.trial_dx = r.predicted_dx();
    ls.direction = step;
    step = target - r.s;
    *search_start = Clock::now();
    // The full step first (Gauss–Newton's natural guess). It is taken as is when it achieved
    // at least full_step_acceptance of the model's decrease (and no tet was clamped, which
    // would change the step); otherwise a more damped direction is tried
    // (damped_step_trials), and after the last one Brent searches [0, max_step] (§3.4).
    const double full = ls.phi(std::min(1.0, options.max_step));
    // With damped trials the test is on Φ at the clamped state itself (a few tets at the
    // floor need not spoil a step that achieves the model's decrease); without, as before.
    *full_step_good = (record.clamped_tets == 0 || options.damped_step_trials > 0) &&
                      options.full_step_acceptance > 0.0 && record.predicted_decrease > 0.0 &&
                      before - full >= options.full_step_acceptance * record.predicted_decrease;
    // The best state of all trials is taken (phi keeps it), usually this full step.
    if (*full_step_good) return true;
    if (trial >= options.damped_step_trials) return true;
    damping = damping == 0.0 ? options.damping_start : damping * options.damping_growth;
  }
}

// Whether a stage ends after an iteration that took a step (the last of summary.iterations), and
// why (termination). The stopping tests wait while the ICP stage ramps its weights up.
bool stage_converged(RegistrationStage stage, RegistrationStage final_stage, double before,
                     bool ramping, const GaussNewtonOptions& options,
                     const GaussNewtonSummary& summary, GaussNewtonTermination& termination) {
  const GaussNewtonIteration& record = summary.iterations.back();
  if (ramping) return false;
  if ((stage == RegistrationStage::kIcpMarkers ||
       (stage == RegistrationStage::kLandmarks && stage != final_stage)) &&
      options.max_marker_error > 0.0 && record.marker_error_max <= options.max_marker_error) {
    // The ICP stage's markers met; or the landmarks met in a landmark stage that only
    // prepares the ICP stage (its further iterations polish the smoothness the ICP stage
    // changes anyway: 10-20 iterations of relative decreases ~1e-5 on the vertebrae).
    termination = GaussNewtonTermination::kMarkerTolerance;
    return true;
  }
  if (record.step < options.min_step) {
    termination = GaussNewtonTermination::kSmallStep;
    return true;
  }
  if (before - record.objective <= options.relative_decrease_tolerance * before) {
    termination = GaussNewtonTermination::kSmallDecrease;
    return true;
  }
  if (stage == RegistrationStage::kIcpMarkers && options.icp_no_progress_iterations > 0) {
    // Φ after each iteration at the full weights (icp_no_progress_iterations): iterations
    // since the last one that lowered the stage's best by relative_decrease_tolerance.
    double best_after = kInfinity;
    int since_best = 0;
    for (const GaussNewtonIteration& it : summary.iterations) {
      const bool it_ramping =
          static_cast<std::size_t>(it.iteration) <= options.icp_weight_ramp.size() ||
          it.iteration <= options.icp_point_to_plane_iterations;
      if (it.stage != stage || it_ramping || !(it.step > 0.0)) continue;
      if (it.objective < (1.0 - options.relative_decrease_tolerance) * best_after) {
        best_after = it.objective;
        since_best = 0;
      } else {
        ++since_best;
      }
    }
    if (since_best >= options.icp_no_progress_iterations) {
      termination = GaussNewtonTermination::kSmallDecrease;
      return true;
    }
  }
  return false;
}

// How an iteration ended: go on (its state is checkpointed), the stage is done (checkpointed
// too), stop the stage at once (nothing to fit, a failed linear solve: termination says which),
// or the objective could not be formed (error).
enum class IterationEnd { kNext, kStageDone, kStop, kInvalidInput };

// One Gauss–Newton iteration of a stage (§3.4-3.5): the weights of this iteration, the step
// (damped_step_trials), the line search, the new state, its record and the stopping tests.
IterationEnd gauss_newton_iteration(Registration& r, RegistrationStage stage, int iteration,
                                    RegistrationStage final_stage, bool free,
                                    const GaussNewtonOptions& options, GaussNewtonSummary& summary,
                                    const GaussNewtonProgress& progress, Eigen::VectorXd& step,
                                    GaussNewtonTermination& termination, std::string& error) {
  const Clock::time_point start = Clock::now();
  const int solves_before = r.equilibrium_solves;
  GaussNewtonIteration record;
  record.stage = stage;
  record.iteration = iteration;
  // A function of the iteration alone, so that a resumed run weighs exactly as the first.
  const bool weight_ramp = stage == RegistrationStage::kIcpMarkers &&
                           static_cast<std::size_t>(iteration) <= options.icp_weight_ramp.size();
  const bool plane_phase =
      stage == RegistrationStage::kIcpMarkers && iteration <= options.icp_point_to_plane_iterations;
  const bool ramping = weight_ramp || plane_phase;  // the stopping tests wait for both
  r.set_icp_weight_scale(
      weight_ramp ? options.icp_weight_ramp[static_cast<std::size_t>(iteration - 1)] : 1.0);
  r.set_icp_point_to_plane(plane_phase);
  auto terms = r.objective_constraints(stage, r.x, &error);
  if (!terms) return IterationEnd::kInvalidInput;
  const double before = r.objective(r.s, r.x, *terms);
  record.objective_before = before;
  // Nothing (left) to fit in this stage, e.g. attachments already met: Φ is round-off.
  if (before <= 1e-12 * summary.initial_objective) {
    termination = GaussNewtonTermination::kSmallDecrease;
    return IterationEnd::kStop;
  }
  if (r.free_object() && !r.set_stabilisation(*terms, r.x, &error)) {
    termination = GaussNewtonTermination::kLinearSolveFailed;
    summary.message = error;
    return IterationEnd::kStop;
  }
  // The damping to start from: the last iteration's, relaxed (damped_step_trials).
  double damping = 0.0;
  if (options.damped_step_trials > 0 && !summary.iterations.empty()) {
    damping = summary.iterations.back().damping / options.damping_growth;
    if (damping < options.damping_start) damping = 0.0;
  }
  LineSearch ls(r, options, *terms, step, before);
  bool full_step_good = false;
  Clock::time_point search_start = Clock::now();
  if (!damped_step_trials(ls, stage, before, ramping, damping, record, &full_step_good,
                          &search_start, error)) {
    termination = GaussNewtonTermination::kLinearSolveFailed;
    summary.message = error;
    return IterationEnd::kStop;
  }
  if (!full_step_good) ls.search();
  if (ls.best_eta <= 0.0 && record.clamped_tets > 0 && options.projected_search_fallback) {
    ls.projected = true;  // its full step is clamp(s + d), already tried
    record.projected_search = true;
    ls.search();
  }
  record.inverted_equilibrium = ls.take_inverted();
  record.line_search_seconds = seconds_since(search_start);
  record.equilibrium_solves = r.equilibrium_solves - solves_before;
  const bool took_step = ls.best_eta > 0.0;
  if (!took_step) {
    record.objective = before;
    termination = GaussNewtonTermination::kLineSearchFailed;
  } else {
    ls.projected = ls.best_projected;
    r.s = ls.best_s;
    r.x = ls.best_x;
    if (free) r.rigid_update(stage, r.x, rigid_rounds(stage));
    record.step = ls.best_eta;
    record.objective = ls.best_value;
  }
  std::tie(record.marker_error_mean, record.marker_error_max) = r.marker_errors(stage, r.x);
  record.seconds = seconds_since(start);
  summary.iterations.push_back(record);
  if (progress) progress(record);
  const bool stage_done = took_step ? stage_converged(stage, final_stage, before, ramping, options,
                                                      summary, termination)
                                    : !ramping;
  return stage_done ? IterationEnd::kStageDone : IterationEnd::kNext;
}

RegistrationResult run_registration(const PlasticElasticEnergy& energy_in,
                                    const RegistrationConstraints& constraints,
                                    ClosestSurfacePoint* closest_point,
                                    const GaussNewtonOptions& options,
                                    const GaussNewtonProgress& progress,
                                    const GaussNewtonCheckpointCallback& checkpoint,
                                    const GaussNewtonCheckpoint* resume, bool free) {
  const Clock::time_point run_start = Clock::now();
  RegistrationResult result;
  result.s = identity_plastic_strains(energy_in.num_tets());
  result.x = energy_in.rest_dofs();
  GaussNewtonSummary& summary = result.summary;
  auto fail = [&](GaussNewtonTermination termination, const std::string& message) {
    summary.termination = termination;
    summary.message = message;
    summary.seconds = seconds_since(run_start);
    return result;
  };
  if (auto message = invalid_registration_input(energy_in, constraints, closest_point, options,
                                                resume, free)) {
    return fail(GaussNewtonTermination::kInvalidInput, *message);
  }
  // Exact stiffness in full storage for the Jacobian (eq. 10).
  PlasticElasticEnergyOptions exact_options;
  exact_options.projection = common::HessianProjection::kNone;
  exact_options.storage = common::PatternStorage::kFull;
  auto energy = PlasticElasticEnergy::create(rest_matrix(energy_in), energy_in.tets(),
                                             energy_in.material(), exact_options);
  if (!energy) return fail(GaussNewtonTermination::kInvalidInput, "tet mesh rejected");
  ConstraintCheck check;
  auto springs =
      PointConstraints::create(energy->num_vertices(), energy->tets(), constraints.attachments,
                               common::PatternStorage::kFull, &check);
  if (!springs)
    return fail(GaussNewtonTermination::kInvalidInput, "attachments: " + check.message());
  std::string error;
  auto equilibrium = EquilibriumSolver::create(*energy, *springs, options.equilibrium, &error);
  // The template's first equilibrium may need to pass through inverted tets (a twisted bar):
  // rejecting inversions there left the line search stuck (Botsch–Sorkine bar, 135°), so the
  // fallback solves below allow them; the stable neo-Hookean energy is finite when inverted.
  EquilibriumOptions first_options = options.equilibrium;
  first_options.reject_inversions = false;
  auto first_equilibrium = EquilibriumSolver::create(*energy, *springs, first_options, &error);
  if (!equilibrium || !first_equilibrium) {
    return fail(GaussNewtonTermination::kInvalidInput, error);
  }
  const PlasticStrainLaplacian laplacian = make_plastic_strain_laplacian(energy->tets());
  auto woodbury =
      WoodburySolver::create(laplacian.adjacency, energy->num_tets(), options.woodbury, &error);
  if (!woodbury) return fail(GaussNewtonTermination::kInvalidInput, error);

  Registration r(std::move(*energy), *springs, std::move(*equilibrium), std::move(*woodbury),
                 laplacian.matrix, constraints, closest_point, options);
  r.s = result.s;
  r.x = result.x;
  const std::vector<RegistrationStage> stages = registration_stages(constraints, options, free);
  const RegistrationStage final_stage = stages.back();
  // The stage to start with (stages.size(): all done) and its first iteration.
  std::size_t first_stage = 0;
  int first_iteration = 1;
  double seconds_before = 0.0;  // a resumed run's earlier registration time
  if (resume != nullptr) {
    if (!resume_state(*resume, stages, r, summary, &first_stage, &first_iteration, &error)) {
      return fail(GaussNewtonTermination::kInvalidInput, error);
    }
    seconds_before = resume->seconds;
  }
  // Hands the state to continue from to the caller (checkpoints).
  const auto save = [&](std::optional<RegistrationStage> next_stage, int next_iteration,
                        GaussNewtonTermination last_termination) {
    if (!checkpoint) return;
    GaussNewtonCheckpoint saved;
    saved.free_object = free;
    saved.next_stage = next_stage;
    saved.next_iteration = next_iteration;
    saved.termination = last_termination;
    saved.s = r.s;
    saved.x = r.x;
    saved.iterations = summary.iterations;
    saved.initial_objective = summary.initial_objective;
    saved.equilibrium_solves = r.equilibrium_solves;
    saved.seconds = seconds_before + seconds_since(run_start);
    checkpoint(saved);
  };
  if (free && resume == nullptr) align_free_object(r, energy_in, constraints);
  if (resume == nullptr && !free && !r.solve_equilibrium(r.s, r.x) &&
      !first_attached_equilibrium(r, *springs, *first_equilibrium, energy_in, constraints,
                                  options)) {
    return fail(GaussNewtonTermination::kEquilibriumFailed,
                "no static equilibrium of the template under the attachments (also not with "
                "inversions allowed, nor by " +
                    std::to_string(options.first_equilibrium_steps) + " load steps)");
  }

  if (resume == nullptr) {
    auto terms = r.objective_constraints(final_stage, r.x, &error);
    if (!terms) return fail(GaussNewtonTermination::kInvalidInput, error);
    summary.initial_objective = r.objective(r.s, r.x, *terms);
  }

  if (options.initial_constant_fit && resume == nullptr) {
    if (!initial_constant_fit(r, free, final_stage, options, summary, progress, error)) {
      return fail(GaussNewtonTermination::kInvalidInput, error);
    }
    save(stages.front(), 1, GaussNewtonTermination::kMaxIterations);
  }

  GaussNewtonTermination termination = resume != nullptr && !resume->next_stage
                                           ? resume->termination
                                           : GaussNewtonTermination::kMaxIterations;
  Eigen::VectorXd step;
  for (std::size_t stage_index = first_stage; stage_index < stages.size(); ++stage_index) {
    const RegistrationStage stage = stages[stage_index];
    termination = GaussNewtonTermination::kMaxIterations;
    for (int iteration = stage_index == first_stage ? first_iteration : 1;
         iteration <= options.max_iterations_per_stage; ++iteration) {
      const IterationEnd end =
          gauss_newton_iteration(r, stage, iteration, final_stage, free, options, summary, progress,
                                 step, termination, error);
      if (end == IterationEnd::kInvalidInput) {
        return fail(GaussNewtonTermination::kInvalidInput, error);
      }
      if (end == IterationEnd::kStop) break;
      const bool stage_done = end == IterationEnd::kStageDone;
      // The checkpoint names what runs next: this stage's next iteration, or the next stage.
      if (stage_done || iteration == options.max_iterations_per_stage) {
        save(
            stage_index + 1 < stages.size() ? std::optional(stages[stage_index + 1]) : std::nullopt,
            1, termination);
      } else {
        save(stage, iteration + 1, termination);
      }
      if (stage_done) break;
    }
    if (termination == GaussNewtonTermination::kLinearSolveFailed) break;
  }

  result.s = r.s;
  result.x = r.x;
  {
    auto terms = r.objective_constraints(final_stage, r.x, &error);
    summary.final_objective = terms ? r.objective(r.s, r.x, *terms) : kInfinity;
  }
  std::tie(summary.marker_error_mean, summary.marker_error_max) = r.marker_errors(final_stage, r.x);
  // A stall is not convergence (issue 51): the femur bent and bulged ended its ICP stage by
  // small-decrease with the markers 19.5 mm off on average (tolerance 0.46 mm at the largest).
  if ((termination == GaussNewtonTermination::kSmallDecrease ||
       termination == GaussNewtonTermination::kSmallStep) &&
      options.max_marker_error > 0.0 && summary.marker_error_mean > options.max_marker_error) {
    summary.message = fmt::format(
        "stalled: the {} stage ended by {} with its markers on average {:.3g}x the marker "
        "tolerance from their targets (largest {:.3g}x)",
        to_string(final_stage), to_string(termination),
        summary.marker_error_mean / options.max_marker_error,
        summary.marker_error_max / options.max_marker_error);
    termination = GaussNewtonTermination::kStalled;
  }
  summary.termination = termination;
  summary.equilibrium_solves = r.equilibrium_solves;
  summary.seconds = seconds_before + seconds_since(run_start);
  return result;
}

// The scan's side of a free object's constraints moved rigidly onto the template (issue 18: the
// person's scan in any pose). Π and the fit are rigid-invariant, but the arithmetic is not: run
// in the scan's frame, sub-verse013 rotated by 90° about (1, 2, 3) ended 1.9 mm (1.8e-2 of the
// diagonal) from the unrotated result at worst, since an iteration amplifies a last-bit
// difference ~1e7-fold (docs/registration.md). So the landmark targets and ICP markers are moved
// by the rigid fit of the landmarks' targets to their template points (else the markers' centroid
// to the template's: the ICP alignment after it depends on the pose anyway) and rounded to
// multiples of 2⁻²⁶ of the template's diagonal (1.5e-6 mm on a 100 mm bone), far coarser than the
// transform's rounding (~1e-15 of the diagonal): a rotated scan then gives the same bits as the
// unrotated one unless one of its coordinates lies within that rounding of a grid boundary
// (for 160 points, a chance of about 1e-4).
RigidTransform scan_to_template(const PlasticElasticEnergy& energy,
                                const RegistrationConstraints& constraints) {
  const Eigen::VectorXd rest = energy.rest_dofs();
  if (constraints.landmarks.size() >= 3) {
    std::vector<Eigen::Vector3d> from, to;
    for (const PointConstraint& c : constraints.landmarks) {
      from.push_back(c.target);
      to.push_back(embedded_position(energy.tets(), c.point, rest));
    }
    if (const auto fit = fit_rigid_transform(from, to)) return *fit;
  }
  Eigen::Vector3d scan = Eigen::Vector3d::Zero(), vertices = Eigen::Vector3d::Zero();
  std::size_t count = 0;
  for (const PointConstraint& c : constraints.landmarks) {
    scan += c.target;
    ++count;
  }
  for (const Eigen::Vector3d& z : constraints.icp_markers) {
    scan += z;
    ++count;
  }
  if (count > 0) scan /= static_cast<double>(count);
  for (Eigen::Index v = 0; v < rest.size() / 3; ++v) vertices += rest.segment<3>(3 * v);
  if (rest.size() > 0) vertices /= static_cast<double>(rest.size() / 3);
  return RigidTransform{Eigen::Matrix3d::Identity(), vertices - scan};
}

}  // namespace

RegistrationResult register_attached(const PlasticElasticEnergy& energy,
                                     const RegistrationConstraints& constraints,
                                     ClosestSurfacePoint* closest_point,
                                     const GaussNewtonOptions& options,
                                     const GaussNewtonProgress& progress,
                                     const GaussNewtonCheckpointCallback& checkpoint,
                                     const GaussNewtonCheckpoint* resume) {
  return run_registration(energy, constraints, closest_point, options, progress, checkpoint, resume,
                          false);
}

RegistrationResult register_free(const PlasticElasticEnergy& energy,
                                 const RegistrationConstraints& constraints,
                                 ClosestSurfacePoint* closest_point,
                                 const GaussNewtonOptions& options,
                                 const GaussNewtonProgress& progress,
                                 const GaussNewtonCheckpointCallback& checkpoint,
                                 const GaussNewtonCheckpoint* resume) {
  const RigidTransform to_template = scan_to_template(energy, constraints);
  const Eigen::VectorXd rest = energy.rest_dofs();
  double diagonal = 0.0;
  if (rest.size() >= 3) {
    const auto points = rest.reshaped(3, rest.size() / 3);
    diagonal = (points.rowwise().maxCoeff() - points.rowwise().minCoeff()).norm();
  }
  const double grid = std::ldexp(1.0, (diagonal > 0.0 ? std::ilogb(diagonal) : 0) - 26);
  const auto moved = [&](const Eigen::Vector3d& p) -> Eigen::Vector3d {
    return (to_template.apply(p) / grid).array().round() * grid;
  };
  RegistrationConstraints local = constraints;
  for (PointConstraint& c : local.landmarks) c.target = moved(c.target);
  for (Eigen::Vector3d& z : local.icp_markers) z = moved(z);
  RegistrationResult result =
      run_registration(energy, local, closest_point, options, progress, checkpoint, resume, true);
  // Back to the scan's frame (the checkpoints stay in the template's: a resumed run moves the
  // same constraints the same way).
  const RigidTransform to_scan{to_template.rotation.transpose(),
                               -(to_template.rotation.transpose() * to_template.translation)};
  to_scan.apply_to_dofs(result.x);
  return result;
}

}  // namespace sinew::offline
