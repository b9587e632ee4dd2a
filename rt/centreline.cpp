#include "rt/centreline.hpp"

#include <cmath>

namespace sinew::rt {

HermiteElement hermite_element(const Eigen::Vector2d& X1,
                               const common::BeamElementReference& reference,
                               const Eigen::Vector2d& T1, const Eigen::Vector2d& T2,
                               const common::Vector6d& u_e) {
  HermiteElement h;
  h.L0 = reference.length;
  h.D = reference.chord / h.L0;
  h.x1 = X1 + u_e.segment<2>(0);
  h.x2 = X1 + reference.chord + u_e.segment<2>(3);
  const double c1 = std::cos(u_e[2]), s1 = std::sin(u_e[2]);
  const double c2 = std::cos(u_e[5]), s2 = std::sin(u_e[5]);
  h.t1 = Eigen::Vector2d(c1 * T1.x() - s1 * T1.y(), s1 * T1.x() + c1 * T1.y());
  h.t2 = Eigen::Vector2d(c2 * T2.x() - s2 * T2.y(), s2 * T2.x() + c2 * T2.y());
  return h;
}

CentrelinePoint hermite_point(const HermiteElement& h, double xi) {
  const double L0 = h.L0;
  const Eigen::Vector2d &x1 = h.x1, &x2 = h.x2, &t1 = h.t1, &t2 = h.t2;
  const Eigen::Vector2d dt1(-t1.y(), t1.x()), dt2(-t2.y(), t2.x());  // ∂t/∂θ

  const double xi2 = xi * xi, xi3 = xi2 * xi;
  const double h00 = 2 * xi3 - 3 * xi2 + 1, h10 = xi3 - 2 * xi2 + xi;
  const double h01 = -2 * xi3 + 3 * xi2, h11 = xi3 - xi2;
  const double d00 = 6 * xi2 - 6 * xi, d10 = 3 * xi2 - 4 * xi + 1;
  const double d01 = -6 * xi2 + 6 * xi, d11 = 3 * xi2 - 2 * xi;

  CentrelinePoint p;
  p.position = h00 * x1 + h10 * L0 * t1 + h01 * x2 + h11 * L0 * t2;
  Eigen::Vector2d tangent = d00 * x1 + d10 * L0 * t1 + d01 * x2 + d11 * L0 * t2;
  const double norm = tangent.norm();
  tangent = norm > 0 ? Eigen::Vector2d(tangent / norm) : h.D;
  p.normal = Eigen::Vector2d(-tangent.y(), tangent.x());
  p.jacobian.setZero();
  p.jacobian(0, 0) = p.jacobian(1, 1) = h00;
  p.jacobian(0, 3) = p.jacobian(1, 4) = h01;
  p.jacobian.col(2) = h10 * L0 * dt1;
  p.jacobian.col(5) = h11 * L0 * dt2;
  return p;
}

CentrelinePoint hermite_centreline(const Eigen::Vector2d& X1,
                                   const common::BeamElementReference& reference,
                                   const Eigen::Vector2d& T1, const Eigen::Vector2d& T2,
                                   const common::Vector6d& u_e, double xi) {
  return hermite_point(hermite_element(X1, reference, T1, T2, u_e), xi);
}

Eigen::Matrix2Xd polyline_node_tangents(const Eigen::Matrix2Xd& nodes) {
  const Eigen::Index n = nodes.cols();
  Eigen::Matrix2Xd T(2, n);
  if (n < 2) return T.setZero();
  for (Eigen::Index i = 1; i + 1 < n; ++i) {
    T.col(i) = ((nodes.col(i) - nodes.col(i - 1)).normalized() +
                (nodes.col(i + 1) - nodes.col(i)).normalized())
                   .normalized();
  }
  const Eigen::Vector2d first = (nodes.col(1) - nodes.col(0)).normalized();
  const Eigen::Vector2d last = (nodes.col(n - 1) - nodes.col(n - 2)).normalized();
  if (n == 2) {
    T.col(0) = first;
    T.col(1) = last;
  } else {
    T.col(0) = (2.0 * first - T.col(1)).normalized();
    T.col(n - 1) = (2.0 * last - T.col(n - 2)).normalized();
  }
  return T;
}

}  // namespace sinew::rt
