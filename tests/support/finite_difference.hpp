#pragma once
/// Finite-difference checks shared by every derivative test (tet energy, material, beam element,
/// polar decomposition, plastic energy). One checker, used everywhere: gradients against
/// differences of the value, Hessians/Jacobians against differences of the analytic gradient, and a
/// guard that the compared quantity is not zero (comparing zeros proves nothing).

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <functional>
#include <random>
#include <sstream>

namespace sinew::testing {

using ScalarFunction = std::function<double(const Eigen::VectorXd&)>;
using VectorFunction = std::function<Eigen::VectorXd(const Eigen::VectorXd&)>;

/// Fourth-order central differences of a scalar function: error O(h^4).
inline Eigen::VectorXd fd_gradient(const ScalarFunction& f, const Eigen::VectorXd& x, double h) {
  Eigen::VectorXd g(x.size());
  Eigen::VectorXd xp = x;
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    const double xi = x[i];
    xp[i] = xi + h;
    const double f1 = f(xp);
    xp[i] = xi - h;
    const double fm1 = f(xp);
    xp[i] = xi + 2 * h;
    const double f2 = f(xp);
    xp[i] = xi - 2 * h;
    const double fm2 = f(xp);
    xp[i] = xi;
    g[i] = (-f2 + 8 * f1 - 8 * fm1 + fm2) / (12 * h);
  }
  return g;
}

/// Fourth-order central differences of a vector function; column i is d g / d x_i.
inline Eigen::MatrixXd fd_jacobian(const VectorFunction& g, const Eigen::VectorXd& x, double h) {
  const Eigen::VectorXd g0 = g(x);
  Eigen::MatrixXd J(g0.size(), x.size());
  Eigen::VectorXd xp = x;
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    const double xi = x[i];
    xp[i] = xi + h;
    const Eigen::VectorXd g1 = g(xp);
    xp[i] = xi - h;
    const Eigen::VectorXd gm1 = g(xp);
    xp[i] = xi + 2 * h;
    const Eigen::VectorXd g2 = g(xp);
    xp[i] = xi - 2 * h;
    const Eigen::VectorXd gm2 = g(xp);
    xp[i] = xi;
    J.col(i) = (-g2 + 8 * g1 - 8 * gm1 + gm2) / (12 * h);
  }
  return J;
}

/// Compares an analytic derivative with its finite-difference estimate in the Frobenius norm:
/// passes when |analytic - fd| <= rel_tol * |fd| and |fd| >= min_norm (the non-zero guard).
template <typename A, typename B>
::testing::AssertionResult derivatives_match(const Eigen::MatrixBase<A>& analytic,
                                             const Eigen::MatrixBase<B>& fd, double rel_tol,
                                             double min_norm = 1e-8) {
  if (analytic.rows() != fd.rows() || analytic.cols() != fd.cols()) {
    return ::testing::AssertionFailure()
           << "shape mismatch: analytic " << analytic.rows() << "x" << analytic.cols() << ", fd "
           << fd.rows() << "x" << fd.cols();
  }
  if (!analytic.allFinite()) return ::testing::AssertionFailure() << "analytic has NaN/inf";
  const double fd_norm = fd.norm();
  if (fd_norm < min_norm) {
    return ::testing::AssertionFailure()
           << "finite-difference derivative is (near) zero, |fd| = " << fd_norm << " < " << min_norm
           << ": the check would prove nothing";
  }
  const double err = (analytic - fd).norm();
  if (err > rel_tol * fd_norm) {
    std::ostringstream s;
    s << "relative error " << err / fd_norm << " > " << rel_tol << " (|fd| = " << fd_norm
      << ")\nanalytic:\n"
      << analytic << "\nfinite differences:\n"
      << fd;
    return ::testing::AssertionFailure() << s.str();
  }
  return ::testing::AssertionSuccess() << "relative error " << err / fd_norm;
}

/// Seeded generator so every derivative test is reproducible.
inline std::mt19937& rng(unsigned seed = 20261123u) {
  static std::mt19937 gen(seed);
  return gen;
}

/// Uniform random vector in [-scale, scale]^n.
inline Eigen::VectorXd random_vector(Eigen::Index n, double scale, std::mt19937& gen) {
  std::uniform_real_distribution<double> u(-scale, scale);
  Eigen::VectorXd v(n);
  for (Eigen::Index i = 0; i < n; ++i) v[i] = u(gen);
  return v;
}

/// Rotation by angle (radians) about axis (any non-zero length), by Rodrigues' formula.
inline Eigen::Matrix3d rotation_about(const Eigen::Vector3d& axis, double angle) {
  return Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
}

/// Uniformly distributed random rotation (normalised Gaussian quaternion), det = +1.
inline Eigen::Matrix3d random_rotation(std::mt19937& gen) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Vector4d c;
  for (int i = 0; i < 4; ++i) c[i] = n(gen);  // sequenced: argument order is unspecified
  const Eigen::Quaterniond q(c.normalized());
  return q.toRotationMatrix();
}

/// Random 3x3 matrix U·diag(singular_values)·Vᵀ with random rotations U, V: controls conditioning
/// (and, with a negative entry, inversion) of deformation gradients in tests.
inline Eigen::Matrix3d matrix_with_singular_values(const Eigen::Vector3d& singular_values,
                                                   std::mt19937& gen) {
  return random_rotation(gen) * singular_values.asDiagonal() * random_rotation(gen).transpose();
}

}  // namespace sinew::testing
