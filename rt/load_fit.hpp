#pragma once
/// The loads at a few points of a beam that best explain a tracked shape: the well-posed inverse
/// problem beside the per-node forces p(u), which explain any shape and so amplify its noise.
///
/// Minimises Σ_i w_i |x_i(u(q)) − x̂_i|² (positions, and rotations as arcs over one element) over
/// the loads q at the load points, u(q) the equilibrium of a subdivided copy of the beam under q
/// alone (its O(h²) error would otherwise read as a load error of a few per cent), w_i Tukey
/// weights (a local kink that clutter or an occluder left in the tracked shape does not move the
/// loads). Load points are nodes of the subdivided beam, chosen per call, so a contact point may
/// move along the beam. The beam's fixed dofs are its supports; they take the tracked state's
/// values (a clamped base that moves with the face).
///
/// Two methods, the same loads at convergence:
/// - coupled (default): Gauss–Newton on q and u together: the equilibrium p(u) = E q is linearised
///   at u, so du = −K_T⁻¹r + K_T⁻¹E dq (r = p(u) − E q), and dq minimises the misfit of u + du.
///   One factorisation per iteration; it needs no equilibrium to start from and starts from the
///   tracked shape.
/// - nested (the fallback): Gauss–Newton over q with the equilibrium solved to 1e-8 inside every
///   iteration (StaticBeamSolver), from the last call's state.
/// All memory is sized at construction; fit() does not allocate.

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <array>
#include <optional>
#include <string>

#include "common/beam/beam_model.hpp"
#include "common/beam/block_tridiagonal.hpp"
#include "common/beam/static_solver.hpp"

namespace sinew::rt {

struct LoadFitOptions {
  /// Gauss–Newton iterations of the nested fit, ≥ 1; the coupled fit may take twice as many.
  int max_iterations = 6;
  /// Also fit a moment at each load point. A contact transmits a force, and a free moment trades
  /// off against it.
  bool fit_moments = false;
  /// Sub-elements per element of the beam the loads are fitted on, ≥ 1.
  int subdivisions = 4;
  /// The coupled fit first (the nested one where it does not converge), or the nested one only.
  bool coupled = true;
  /// Most load points of one call, in [1, 64].
  int max_load_points = 8;
  /// Also fit the angle of a clamped first node (a whisker's follicle): its support rotation is
  /// the tracked value plus a fitted offset, so the whole shape sets the angle, not the tracked
  /// first element alone (whose angle noise would otherwise read as a load). Needs node 0's
  /// rotation fixed.
  bool fit_base_rotation = false;
  /// Also fit the position of a clamped first node: its support is the tracked position plus a
  /// fitted offset, so the whole shape sets it, not the tracked first node alone. Where the image
  /// beside a follicle is biased (a whisker's first node sits 0.2–0.4 px sideways under a large
  /// load) the clamp at the tracked node reads the load short. Needs node 0's translation fixed.
  bool fit_base_translation = false;

  std::optional<std::string> validate() const;
};

struct LoadFitSummary {
  bool converged = false;  ///< a step moved no node by more than 1e-3 px
  /// state() is the beam's equilibrium under loads(): an answer, converged or not within
  /// max_iterations. False: the fit failed (no equilibrium was found) and loads() and state()
  /// mean nothing.
  bool equilibrium = false;
  bool coupled = false;  ///< the coupled method gave the answer
  int iterations = 0;    ///< Gauss–Newton iterations of the method that answered
  double rms_px = 0.0;   ///< RMS misfit between the fitted equilibrium and the tracked nodes
  /// The tracked nodes' noise the fit's covariance assumes, pixels per coordinate: the
  /// Tukey-weighted misfit over the measurements less the parameters fitted (rotations count as
  /// arcs over one element). NaN without an equilibrium or with no more measurements than
  /// parameters.
  double noise_px = 0.0;
};

class LoadFit {
 public:
  /// beam: the tracked beam (its rest shape, sections and fixed dofs; the fixed dofs must hold
  /// it). Check valid().
  LoadFit(const common::BeamDescription& beam, LoadFitOptions options);

  bool valid() const { return error_.empty(); }
  const std::string& error() const { return error_; }
  const LoadFitOptions& options() const { return options_; }
  /// The subdivided beam; load points are its nodes. Tracked node i is its node i·subdivisions.
  const common::BeamModel& model() const { return model_; }
  int fine_node(int tracked_node) const { return tracked_node * parts_; }

  /// Fits loads at the subdivided beam's nodes points[0..count) to the tracked state `tracked`
  /// (3 dofs per tracked node, Tracker::state()). Count in [1, max_load_points], nodes distinct
  /// and in range (not checked here: the caller validates them once). With `directions` (2 per
  /// point, unit vectors), each point carries a force along its direction only, one parameter
  /// (a frictionless contact pushes along the normal: the axial part of a point force barely
  /// shows in the shape, and left free it wanders and corrupts the rest). No allocation while
  /// the number of parameters stays the same from call to call.
  ///
  /// With `fractions` (one per point, in [0, 1); needs `directions`), point k's force acts that
  /// fraction of the way from fine node points[k] to the next: as the consistent nodal loads of a
  /// point force on that fine element (cubic Hermite: the forces and moments at its two nodes that
  /// do the same work), its part along the element taken linearly; the element's axes are the
  /// tracked chord's about it. A contact then sits where it is measured instead of at the nearest
  /// fine node (on the shared renderer's exact elastica the snap alone read the follicle moment
  /// 4 % off at the tracker's element length: tests/rt/test_load_fit_elastica.cpp).
  LoadFitSummary fit(const Eigen::Ref<const Eigen::VectorXd>& tracked, const int* points, int count,
                     const double* directions = nullptr,
                     const double* fractions = nullptr) noexcept;
  /// The fitted loads: (2 or 3, or 1 with directions) per load point of the last fit(), in its
  /// order.
  Eigen::Ref<const Eigen::VectorXd> loads() const { return q_.head(params_); }
  /// The fitted offset of node 0's support rotation from the tracked one (radians; 0 unless
  /// options().fit_base_rotation).
  double base_rotation() const { return base_offsets_[2]; }
  /// The fitted offset of node 0's support position from the tracked one (pixels; zero unless
  /// options().fit_base_translation).
  Eigen::Vector2d base_translation() const { return {base_offsets_[0], base_offsets_[1]}; }
  /// The covariance of the last fit's parameters, loads() then the fitted supports of node 0
  /// (rotation, then x and y, as fitted: of the support tracked + offset, which does not depend on
  /// the tracked first node), the tracked coordinates taken as independent with the noise
  /// σ = LoadFitSummary::noise_px (rotations as arcs over one element):
  /// σ² N⁻¹ (Jᵀ W² J + Σ_d (Jᵀ W g_d)(Jᵀ W g_d)ᵀ) N⁻¹, N = Jᵀ W J, J the tracked nodes'
  /// derivatives by the parameters at the answer, W the Tukey weights, g_d their derivatives by
  /// node 0's held (tracked, not fitted) support coordinates: the follicle's own noise moves the
  /// clamp and with it the loads. Other supports are taken as exact. NaN where the fit found no
  /// equilibrium. Square, loads().size() + the fitted supports' count.
  Eigen::Ref<const Eigen::MatrixXd> covariance() const {
    return covariance_.topLeftCorner(params_ + base_, params_ + base_);
  }
  /// The fitted equilibrium state of the subdivided beam.
  const Eigen::VectorXd& state() const { return u_; }
  /// Forgets the last fit: the next starts from the unloaded beam.
  void reset() noexcept;

 private:
  // Sets *equilibrium when it ends at an equilibrium of its loads, converged or not.
  bool coupled(const Eigen::Ref<const Eigen::VectorXd>& tracked, int* iterations,
               bool* equilibrium);
  // Sets *equilibrium when it ends at an equilibrium of its loads, converged or not.
  bool nested(const Eigen::Ref<const Eigen::VectorXd>& tracked, int* iterations, bool* equilibrium);
  bool step(bool robust, bool scaled_ridge);
  // covariance_ and the noise from the last step's weights and Jacobian and the final residual_.
  double update_covariance(bool equilibrium) noexcept;
  void residual(const Eigen::Ref<const Eigen::VectorXd>& tracked, const Eigen::VectorXd& u);
  // consistent_ for this call's points with fractions.
  void consistent_loads(const Eigen::Ref<const Eigen::VectorXd>& tracked, const double* fractions,
                        int count) noexcept;
  // f += sign · E q: this call's loads at their dofs.
  void add_loads(Eigen::VectorXd& f, double sign) const;
  // z = E e_j: the unit load of parameter j, zero on fixed dofs.
  void unit_load(int j, Eigen::Ref<Eigen::VectorXd> z) const;
  void take_supports(const Eigen::Ref<const Eigen::VectorXd>& tracked, Eigen::VectorXd& u) const;
  // The Jacobian columns (tangent solves) of every parameter into columns_ and jacobian_, from
  // tangent_ as evaluated (before its fixed dofs are applied), which it factorises into factor_.
  // False when the factorisation fails.
  // With newton_step, also du_ = −K_T⁻¹ rhs_ (rhs_ zero on fixed dofs) from the same solve.
  bool parameter_columns(bool newton_step);

  LoadFitOptions options_;
  std::string error_;
  common::BeamModel model_;
  common::StaticBeamSolver solver_;
  int parts_ = 1, n_ = 0, per_point_ = 2, params_ = 0;
  // The support dofs of node 0 that are parameters (indices params_ .. params_ + base_ − 1), in
  // this order: its rotation (fit_base_rotation), then x and y (fit_base_translation).
  int base_ = 0;
  int base_dofs_[3] = {2, 0, 1};
  double base_offsets_[3] = {0.0, 0.0, 0.0};  // the last fit's support offsets, by dof
  const int* points_ = nullptr;               // this call's load points
  const double* directions_ = nullptr;        // and their force directions (null: free)
  // Per point of this call with a fraction: the unit force's consistent nodal loads on its fine
  // element, force at the first node (x, y), its moment, then the same at the second node.
  bool fractional_ = false;
  std::array<std::array<double, 6>, 64> consistent_{};
  int pp_ = 2;                   // parameters per load point in this call
  double rotation_scale_ = 1.0;  // rotations enter the fit as arc lengths over one element
  Eigen::VectorXd u_, loads_prev_, rhs_, du_, z_, u_backup_;
  Eigen::MatrixXd columns_;  // K_T⁻¹E, one column per load parameter
  Eigen::VectorXd residual_, change_, q_, q_backup_, dq_, g_;
  Eigen::MatrixXd jacobian_, weighted_jacobian_, normal_, covariance_, sandwich_;
  // Node 0's support coupling to fine node 1 at the last parameter_columns(), and the tracked
  // nodes' derivatives by its held support coordinates with their parameter sensitivities.
  Eigen::Matrix3d base_coupling_ = Eigen::Matrix3d::Zero();
  Eigen::MatrixXd support_columns_, support_jacobian_, support_sensitivity_;
  Eigen::VectorXd weights_;  // the last step's Tukey weight per tracked node
  Eigen::LDLT<Eigen::MatrixXd> ldlt_;
  Eigen::VectorXf sorted_;
  common::BlockTridiagonal tangent_;
  common::BlockTridiagonalLdlt factor_;
};

}  // namespace sinew::rt
