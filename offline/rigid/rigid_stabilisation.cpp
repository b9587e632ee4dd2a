#include "offline/rigid/rigid_stabilisation.hpp"

#include <Eigen/SVD>
#include <algorithm>
#include <map>

#include "common/geometry/polar_decomposition.hpp"

namespace sinew::offline {
namespace {

// vee(skew(M)) = ½[M₂₁ − M₁₂, M₀₂ − M₂₀, M₁₀ − M₀₁].
Eigen::Vector3d vee_skew(const Eigen::Matrix3d& M) {
  return 0.5 * Eigen::Vector3d(M(2, 1) - M(1, 2), M(0, 2) - M(2, 0), M(1, 0) - M(0, 1));
}

// ∂g_r/∂vec(Rp) (3x9) for g_r = vee(skew(Rᵀ Rp)): linear in Rp.
Eigen::Matrix<double, 3, 9> rotation_residual_coefficients(const Eigen::Matrix3d& R) {
  Eigen::Matrix<double, 3, 9> coefficients;
  for (int a = 0; a < 9; ++a) {
    Eigen::Matrix3d unit = Eigen::Matrix3d::Zero();
    unit(a % 3, a / 3) = 1.0;
    coefficients.col(a) = vee_skew(R.transpose() * unit);
  }
  return coefficients;
}

}  // namespace

std::optional<RigidStabilisation> RigidStabilisation::create(
    const common::TetIndices& tets, const Eigen::Ref<const Eigen::VectorXd>& rest_dofs,
    const std::vector<EmbeddedPoint>& points, std::string* error) {
  auto fail = [&](const std::string& message) -> std::optional<RigidStabilisation> {
    if (error != nullptr) *error = message;
    return std::nullopt;
  };
  if (points.size() < 3) {
    return fail("rigid stabilisation needs at least 3 marker points (eqs. 19-20), got " +
                std::to_string(points.size()));
  }
  const double w = 1.0 / static_cast<double>(points.size());
  RigidStabilisation s;
  s.num_dofs_ = rest_dofs.size();
  std::vector<Eigen::Vector3d> rest_points;
  for (std::size_t j = 0; j < points.size(); ++j) {
    if (points[j].tet < 0 || points[j].tet >= tets.rows()) {
      return fail("rigid stabilisation: point " + std::to_string(j) + " lies in tet " +
                  std::to_string(points[j].tet) + ", which does not exist");
    }
    rest_points.push_back(embedded_position(tets, points[j], rest_dofs));
    s.rest_centroid_ += w * rest_points.back();
  }
  Eigen::Matrix3d spread = Eigen::Matrix3d::Zero();
  std::map<Eigen::Index, std::pair<double, Eigen::Vector3d>> per_vertex;
  for (std::size_t j = 0; j < points.size(); ++j) {
    const Eigen::Vector3d offset = rest_points[j] - s.rest_centroid_;
    spread += offset * offset.transpose();
    for (int a = 0; a < 4; ++a) {
      auto& entry = per_vertex.try_emplace(tets(points[j].tet, a), 0.0, Eigen::Vector3d::Zero())
                        .first->second;
      entry.first += w * points[j].weights[a];
      entry.second += w * points[j].weights[a] * offset;
    }
  }
  const Eigen::Vector3d singular =
      Eigen::JacobiSVD<Eigen::Matrix3d>(spread).singularValues();  // descending
  if (!(singular[1] > 1e-12 * singular[0])) {
    return fail("rigid stabilisation: the marker points are collinear, eq. 20 fixes no rotation");
  }
  for (const auto& [vertex, weights] : per_vertex) {
    s.vertices_.push_back(vertex);
    s.centroid_weights_.push_back(weights.first);
    s.moment_weights_.push_back(weights.second);
  }
  return s;
}

Eigen::Vector3d RigidStabilisation::centroid(const Eigen::Ref<const Eigen::VectorXd>& x) const {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < vertices_.size(); ++k) {
    c += centroid_weights_[k] * x.segment<3>(3 * vertices_[k]);
  }
  return c;
}

Eigen::Matrix3d RigidStabilisation::covariance(const Eigen::Ref<const Eigen::VectorXd>& x) const {
  Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
  for (std::size_t k = 0; k < vertices_.size(); ++k) {
    C += x.segment<3>(3 * vertices_[k]) * moment_weights_[k].transpose();
  }
  return C;
}

std::optional<RigidFrame> RigidStabilisation::frame(
    const Eigen::Ref<const Eigen::VectorXd>& x) const {
  const common::PolarDecomposition polar = common::polar_decomposition(covariance(x));
  if (polar.status != common::PolarStatus::kSuccess) return std::nullopt;
  return RigidFrame{polar.R, centroid(x) - rest_centroid_};
}

std::optional<Vector6d> RigidStabilisation::residual(const Eigen::Ref<const Eigen::VectorXd>& x,
                                                     const RigidFrame& target) const {
  const common::PolarDecomposition polar = common::polar_decomposition(covariance(x));
  if (polar.status != common::PolarStatus::kSuccess) return std::nullopt;
  Vector6d g;
  g.head<3>() = centroid(x) - rest_centroid_ - target.t;
  g.tail<3>() = vee_skew(target.R.transpose() * polar.R);
  return g;
}

bool RigidStabilisation::jacobian(const Eigen::Ref<const Eigen::VectorXd>& x,
                                  const RigidFrame& target, StabilisationJacobian& G) const {
  const common::PolarDerivatives polar =
      common::polar_decomposition_derivatives(covariance(x), common::PolarDerivativeOrder::kFirst);
  if (polar.status != common::PolarStatus::kSuccess) return false;
  // ∂g_r/∂vec(C) (3x9); vec(C)[c + 3b] = Σ_v x_{v,c} e_{v,b}.
  const Eigen::Matrix<double, 3, 9> dgdC = rotation_residual_coefficients(target.R) * polar.dRdF;
  G.setZero(6, num_dofs_);
  for (std::size_t k = 0; k < vertices_.size(); ++k) {
    const Eigen::Index dof = 3 * vertices_[k];
    G.block<3, 3>(0, dof) = centroid_weights_[k] * Eigen::Matrix3d::Identity();
    for (int c = 0; c < 3; ++c) {
      Eigen::Vector3d column = Eigen::Vector3d::Zero();
      for (int b = 0; b < 3; ++b) column += moment_weights_[k][b] * dgdC.col(c + 3 * b);
      G.block<3, 1>(3, dof + c) = column;
    }
  }
  return true;
}

bool RigidStabilisation::hessian(const Eigen::Ref<const Eigen::VectorXd>& x,
                                 const RigidFrame& target, const Vector6d& lambda,
                                 Eigen::MatrixXd& H) const {
  const common::PolarDerivatives polar =
      common::polar_decomposition_derivatives(covariance(x), common::PolarDerivativeOrder::kSecond);
  if (polar.status != common::PolarStatus::kSuccess) return false;
  // Σ_i λ_{3+i} ∂²g_r,i/∂vec(C)² (9x9): column j is d2RdF2[j]ᵀ·(Σ_i λ_{3+i} coefficients row i).
  const Eigen::Matrix<double, 9, 1> weighted =
      rotation_residual_coefficients(target.R).transpose() * lambda.tail<3>();
  common::Matrix9d HC;
  for (int j = 0; j < 9; ++j)
    HC.col(j) = polar.d2RdF2[static_cast<std::size_t>(j)].transpose() * weighted;
  // Chain rule through the linear map vec(C)[c + 3b] = Σ_v x_{v,c} e_{v,b}.
  const Eigen::Index s = static_cast<Eigen::Index>(vertices_.size());
  H.setZero(3 * s, 3 * s);
  for (Eigen::Index u = 0; u < s; ++u) {
    const Eigen::Vector3d& eu = moment_weights_[static_cast<std::size_t>(u)];
    for (Eigen::Index v = 0; v < s; ++v) {
      const Eigen::Vector3d& ev = moment_weights_[static_cast<std::size_t>(v)];
      Eigen::Matrix3d block = Eigen::Matrix3d::Zero();
      for (int b = 0; b < 3; ++b) {
        for (int bb = 0; bb < 3; ++bb) block += eu[b] * ev[bb] * HC.block<3, 3>(3 * b, 3 * bb);
      }
      H.block<3, 3>(3 * u, 3 * v) = block;
    }
  }
  return true;
}

std::optional<RigidTransform> RigidStabilisation::transform_to(
    const RigidFrame& target, const Eigen::Ref<const Eigen::VectorXd>& x) const {
  const std::optional<RigidFrame> current = frame(x);
  if (!current) return std::nullopt;
  // x' = Q (x − c) + X̄ + t with Q = R_target R_currentᵀ: C(x') = Q C(x), so Polar(C(x')) =
  // R_target, and the centroid moves to X̄ + t.
  RigidTransform transform;
  transform.rotation = target.R * current->R.transpose();
  transform.translation =
      rest_centroid_ + target.t - transform.rotation * (current->t + rest_centroid_);
  return transform;
}

bool RigidStabilisation::move_to(const RigidFrame& target, Eigen::Ref<Eigen::VectorXd> x) const {
  const std::optional<RigidTransform> transform = transform_to(target, x);
  if (!transform) return false;
  transform->apply_to_dofs(x);
  return true;
}

}  // namespace sinew::offline
