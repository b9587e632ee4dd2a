#include "offline/rigid/rigid_motion.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <cmath>

#include "common/geometry/polar_decomposition.hpp"

namespace sinew::offline {

Eigen::Matrix<double, Eigen::Dynamic, 6> rigid_motion_basis(
    const Eigen::Ref<const Eigen::VectorXd>& x, bool orthonormalise) {
  const Eigen::Index n = x.size() / 3;
  Eigen::Matrix<double, Eigen::Dynamic, 6> basis(3 * n, 6);
  basis.setZero();
  for (Eigen::Index v = 0; v < n; ++v) {
    const Eigen::Vector3d p = x.segment<3>(3 * v);
    for (int i = 0; i < 3; ++i) {
      basis(3 * v + i, i) = 1.0;
      basis.block<3, 1>(3 * v, 3 + i) = Eigen::Vector3d::Unit(i).cross(p);
    }
  }
  if (!orthonormalise) return basis;
  Eigen::HouseholderQR<Eigen::Matrix<double, Eigen::Dynamic, 6>> qr(basis);
  return qr.householderQ() * Eigen::Matrix<double, Eigen::Dynamic, 6>::Identity(3 * n, 6);
}

std::optional<std::array<Eigen::Index, 6>> rigid_pin_dofs(
    const Eigen::Ref<const Eigen::VectorXd>& x) {
  const Eigen::Index n = x.size() / 3;
  if (n < 3) return std::nullopt;
  auto point = [&](Eigen::Index v) -> Eigen::Vector3d { return x.segment<3>(3 * v); };
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (Eigen::Index v = 0; v < n; ++v) centroid += point(v);
  centroid /= static_cast<double>(n);
  auto farthest = [&](auto&& distance) {
    Eigen::Index best = 0;
    double best_distance = -1.0;
    for (Eigen::Index v = 0; v < n; ++v) {
      const double d = distance(point(v));
      if (d > best_distance) {
        best_distance = d;
        best = v;
      }
    }
    return std::pair{best, best_distance};
  };
  const Eigen::Index a =
      farthest([&](const Eigen::Vector3d& p) { return (p - centroid).squaredNorm(); }).first;
  const auto [b, ab_length2] =
      farthest([&](const Eigen::Vector3d& p) { return (p - point(a)).squaredNorm(); });
  if (!(ab_length2 > 0.0)) return std::nullopt;
  const Eigen::Vector3d axis = (point(b) - point(a)).normalized();
  const auto [c, c_distance2] =
      farthest([&](const Eigen::Vector3d& p) { return (p - point(a)).cross(axis).squaredNorm(); });
  // Collinear within round-off: no third point fixes the rotation about ab.
  if (!(c_distance2 > 1e-16 * ab_length2)) return std::nullopt;

  std::array<Eigen::Index, 6> pins{};
  for (int i = 0; i < 3; ++i) pins[static_cast<std::size_t>(i)] = 3 * a + i;
  // b: fix the two components across a→b (b slides only along the line), i.e. all but the
  // coordinate axis closest to a→b.
  Eigen::Index along = 0;
  axis.cwiseAbs().maxCoeff(&along);
  int k = 3;
  for (int i = 0; i < 3; ++i) {
    if (i != along) pins[static_cast<std::size_t>(k++)] = 3 * b + i;
  }
  // c: the component that a rotation about ab moves most, axis × (c − a).
  Eigen::Index moved = 0;
  axis.cross(point(c) - point(a)).cwiseAbs().maxCoeff(&moved);
  pins[5] = 3 * c + moved;
  return pins;
}

void pin_dofs(Eigen::SparseMatrix<double>& A, const std::array<Eigen::Index, 6>& pins,
              double diagonal) {
  auto pinned = [&](Eigen::Index i) {
    for (Eigen::Index p : pins) {
      if (p == i) return true;
    }
    return false;
  };
  for (Eigen::Index col = 0; col < A.outerSize(); ++col) {
    const bool col_pinned = pinned(col);
    for (Eigen::SparseMatrix<double>::InnerIterator it(A, col); it; ++it) {
      if (col_pinned || pinned(it.row())) it.valueRef() = it.row() == it.col() ? diagonal : 0.0;
    }
  }
}

void RigidTransform::apply_to_dofs(Eigen::Ref<Eigen::VectorXd> x) const {
  for (Eigen::Index v = 0; v < x.size() / 3; ++v) {
    x.segment<3>(3 * v) = apply(x.segment<3>(3 * v));
  }
}

RigidTransform RigidTransform::after(const RigidTransform& other) const {
  return RigidTransform{rotation * other.rotation, rotation * other.translation + translation};
}

std::optional<RigidTransform> fit_rigid_transform(const std::vector<Eigen::Vector3d>& from,
                                                  const std::vector<Eigen::Vector3d>& to,
                                                  const std::vector<double>& weights) {
  const std::size_t count = from.size();
  if (count < 3 || to.size() != count || (!weights.empty() && weights.size() != count)) {
    return std::nullopt;
  }
  auto weight = [&](std::size_t k) { return weights.empty() ? 1.0 : weights[k]; };
  double total = 0.0;
  Eigen::Vector3d from_mean = Eigen::Vector3d::Zero(), to_mean = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < count; ++k) {
    if (!(weight(k) >= 0.0)) return std::nullopt;
    total += weight(k);
    from_mean += weight(k) * from[k];
    to_mean += weight(k) * to[k];
  }
  if (!(total > 0.0)) return std::nullopt;
  from_mean /= total;
  to_mean /= total;
  // Cross-covariance C = Σ w (z − z̄)(p − p̄)ᵀ: the best rotation is its polar factor (with the
  // reflection case folded into a proper rotation by polar_decomposition).
  Eigen::Matrix3d cross = Eigen::Matrix3d::Zero(), spread = Eigen::Matrix3d::Zero();
  for (std::size_t k = 0; k < count; ++k) {
    const Eigen::Vector3d p = from[k] - from_mean;
    cross += weight(k) * (to[k] - to_mean) * p.transpose();
    spread += weight(k) * p * p.transpose();
  }
  const Eigen::Vector3d spread_eigenvalues =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(spread, Eigen::EigenvaluesOnly).eigenvalues();
  if (!(spread_eigenvalues[1] > 1e-12 * spread_eigenvalues[2])) return std::nullopt;
  const common::PolarDecomposition polar = common::polar_decomposition(cross);
  if (polar.status == common::PolarStatus::kNonFinite) return std::nullopt;
  RigidTransform transform;
  transform.rotation = polar.R;
  transform.translation = to_mean - polar.R * from_mean;
  return transform;
}

}  // namespace sinew::offline
