#include "rt/centreline.hpp"

#include <cmath>

namespace sinew::rt {

namespace {

Eigen::Vector2d rotated(const Eigen::Vector2d& T, double theta) {
  const double c = std::cos(theta), s = std::sin(theta);
  return Eigen::Vector2d(c * T.x() - s * T.y(), s * T.x() + c * T.y());
}

}  // namespace

HermiteElement hermite_element(const Eigen::Vector2d& X1,
                               const common::BeamElementReference& reference,
                               const Eigen::Vector2d& T1, const Eigen::Vector2d& T2,
                               const common::Vector6d& u_e, const HermiteElement* previous) {
  HermiteElement h;
  h.L0 = reference.length;
  h.D = reference.chord / h.L0;
  h.x1 = X1 + u_e.segment<2>(0);
  h.x2 = X1 + reference.chord + u_e.segment<2>(3);
  h.t1 = previous ? previous->t2 : rotated(T1, u_e[2]);
  h.t2 = rotated(T2, u_e[5]);
  return h;
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
