#pragma once
/// What the equilibrium solves' Ipopt adapters share (offline/equilibrium): every dof is unbounded,
/// the constraints (if any) are equalities g(x) = 0, the solve starts from start(), and Ipopt's
/// final point is kept when it is finite (x_final(), finalized()).

#include <IpTNLP.hpp>

#include <Eigen/Core>
#include <algorithm>
#include <utility>

namespace sinew::offline::detail {

class UnboundedIpoptProblem : public Ipopt::TNLP {
 public:
  /// x_initial: what x_final() is until Ipopt reports a finite final point of the same size.
  explicit UnboundedIpoptProblem(Eigen::VectorXd x_initial) : x_final_(std::move(x_initial)) {}

  const Eigen::VectorXd& x_final() const { return x_final_; }
  /// Ipopt reported a finite final point (whatever its return status).
  bool finalized() const { return finalized_; }

  bool get_bounds_info(Ipopt::Index n, Ipopt::Number* x_l, Ipopt::Number* x_u, Ipopt::Index m,
                       Ipopt::Number* g_l, Ipopt::Number* g_u) override {
    // ±1e19 is Ipopt's "no bound" (nlp_lower/upper_bound_inf).
    std::fill(x_l, x_l + n, -1e19);
    std::fill(x_u, x_u + n, 1e19);
    if (m > 0) {
      std::fill(g_l, g_l + m, 0.0);
      std::fill(g_u, g_u + m, 0.0);
    }
    return true;
  }

  bool get_starting_point(Ipopt::Index n, bool init_x, Ipopt::Number* x, bool init_z,
                          Ipopt::Number*, Ipopt::Number*, Ipopt::Index, bool init_lambda,
                          Ipopt::Number*) override {
    if (!init_x || init_z || init_lambda) return false;
    Eigen::Map<Eigen::VectorXd>(x, n) = start();
    return true;
  }

  void finalize_solution(Ipopt::SolverReturn, Ipopt::Index n, const Ipopt::Number* x,
                         const Ipopt::Number*, const Ipopt::Number*, Ipopt::Index,
                         const Ipopt::Number*, const Ipopt::Number*, Ipopt::Number,
                         const Ipopt::IpoptData*, Ipopt::IpoptCalculatedQuantities*) override {
    if (x == nullptr || n != x_final_.size()) return;
    const Eigen::Map<const Eigen::VectorXd> xv(x, n);
    if (!xv.allFinite()) return;
    x_final_ = xv;
    finalized_ = true;
  }

 protected:
  /// The dofs the solve starts from.
  virtual Eigen::Ref<const Eigen::VectorXd> start() const = 0;

 private:
  Eigen::VectorXd x_final_;
  bool finalized_ = false;
};

}  // namespace sinew::offline::detail
