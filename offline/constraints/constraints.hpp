#pragma once
/// Point constraints of seed 003 (§3.1, §3.4 eq. 6, appendix F eqs. 53–56): attachments, landmarks
/// and ICP markers are all material points embedded in a tet of the template mesh, pulled to a
/// world position by a spring,
///   E_c(x) = ½ Σ_k c_k ‖A_k x + b_k‖²,   A_k = [w₁I₃ w₂I₃ w₃I₃ w₄I₃]·S^k (3 x 3n),   b_k = −y_k,
/// with gradient Σ c_k A_kᵀ(A_k x + b_k) (eq. 56: f_a for attachments) and the constant Hessian
/// Σ c_k A_kᵀA_k. A_k x = Σ_a w_a x_{v_a} is the current position of the material point.
///
/// Embedding (TetPointLocator): a template point is given the barycentric weights of the tet that
/// contains it, or of the nearest tet when it lies slightly outside the mesh (bone vertices at a
/// muscle's insertion, §4.1.2; landmarks a little off the surface). Brute force over the tets with
/// bounding-box pruning: fine for the hundreds of constraints of the paper's examples.
///
/// Layout: x is the vertex-major 3n dof vector (metres) of common/fem/sparse_assembly.hpp.

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "common/fem/sparse_assembly.hpp"
#include "common/fem/tet_mesh_elasticity.hpp"

namespace sinew::offline {

/// A material point of the template mesh: tet index and barycentric weights (summing to 1).
struct EmbeddedPoint {
  Eigen::Index tet = 0;
  Eigen::Vector4d weights = Eigen::Vector4d::Constant(0.25);
};

/// Σ_a w_a x_{v_a}: the position of an embedded point for the dof vector x (3n, metres), i.e. A_k
/// x. p.tet must be a row of tets and its vertices must index x.
Eigen::Vector3d embedded_position(const common::TetIndices& tets, const EmbeddedPoint& p,
                                  const Eigen::Ref<const Eigen::VectorXd>& x);

/// What the locator does with a point outside every tet.
enum class OutsidePointPolicy {
  /// Barycentric coordinates of the point itself with respect to the nearest tet (some negative):
  /// the material point is exactly the template point and follows that tet's affine motion.
  kExtrapolate,
  /// Barycentric coordinates of the closest point on the nearest tet (all in [0, 1]): the material
  /// point is moved onto the mesh boundary.
  kProjectToMesh,
};

struct TetPointLocatorOptions {
  /// A point is inside a tet when all its barycentric coordinates are ≥ −inside_tolerance;
  /// dimensionless, in [0, 0.1). Absorbs round-off for points on faces and edges.
  double inside_tolerance = 1e-10;
  /// Points farther than this from the mesh are not embedded (kTooFar); metres, ≥ 0 (not NaN).
  /// Infinity (the default) accepts every point.
  double max_outside_distance = std::numeric_limits<double>::infinity();
  OutsidePointPolicy outside_policy = OutsidePointPolicy::kExtrapolate;
  /// A rest tet is degenerate when |6V₀| ≤ tolerance·(longest edge)³; in [0, 0.1).
  double degeneracy_tolerance = 1e-10;

  /// Empty when valid; otherwise one line naming the field, its value and the constraint.
  std::optional<std::string> validate() const;
};

enum class EmbeddingStatus {
  kInside,     ///< the point is in (or on the boundary of) point.tet
  kOutside,    ///< outside the mesh; embedded in the nearest tet per the outside policy
  kTooFar,     ///< farther than max_outside_distance from the mesh (or the mesh has no tets)
  kNonFinite,  ///< the query point has NaN or infinite coordinates
};

const char* to_string(EmbeddingStatus status);

struct Embedding {
  EmbeddingStatus status = EmbeddingStatus::kNonFinite;
  EmbeddedPoint point;    ///< valid when ok()
  double distance = 0.0;  ///< distance from the query point to point.tet, metres (0 when inside)

  bool ok() const {
    return status == EmbeddingStatus::kInside || status == EmbeddingStatus::kOutside;
  }
};

/// Finds the tet containing (or nearest to) a point of the template (rest) mesh.
class TetPointLocator {
 public:
  /// rest_positions: #V by 3 (metres); tets: #T by 4, right-handed. std::nullopt when the options
  /// or the mesh are invalid; check (if not null) then says why.
  static std::optional<TetPointLocator> create(
      const Eigen::Ref<const Eigen::MatrixXd>& rest_positions, const common::TetIndices& tets,
      const TetPointLocatorOptions& options = {}, common::TetMeshCheck* check = nullptr);

  const TetPointLocatorOptions& options() const { return options_; }
  Eigen::Index num_tets() const { return static_cast<Eigen::Index>(tets_.size()); }

  /// The containing tet if there is one (the first found, for points on shared faces), else the
  /// nearest tet (Euclidean distance to the solid tet). O(#T) per query.
  Embedding locate(const Eigen::Vector3d& point) const;

 private:
  struct Tet {
    Eigen::Matrix<double, 3, 4> X;  // rest vertex positions (columns)
    Eigen::Matrix3d Dm_inv;
    Eigen::Vector3d box_min;
    Eigen::Vector3d box_max;
  };

  explicit TetPointLocator(const TetPointLocatorOptions& options) : options_(options) {}

  TetPointLocatorOptions options_;
  std::vector<Tet> tets_;
};

/// Which kind of observation a constraint is (they share the mathematics, appendix F; the
/// optimisation stages of §3.4 enable them separately).
enum class ConstraintKind {
  kAttachment,  ///< physical spring to another (fixed) object, part of f_net (eq. 4)
  kLandmark,    ///< medical-image landmark with correspondence (eq. 5, first sum)
  kIcpMarker,   ///< closest-point (ICP) marker; point is the current closest surface point
};

const char* to_string(ConstraintKind kind);

struct PointConstraint {
  ConstraintKind kind = ConstraintKind::kLandmark;
  EmbeddedPoint point;                               ///< the material point (S^k and w^k of eq. 53)
  Eigen::Vector3d target = Eigen::Vector3d::Zero();  ///< y_k, world position, metres (b_k = −y_k)
  double weight = 1.0;  ///< c_k, finite and ≥ 0, newtons per metre (energy ½c_k‖·‖² in joules)
  /// Zero (the default): the whole offset counts. A unit vector n: only the offset along n counts
  /// (point to plane: A_k := n·nᵀ·A_k, b_k := n·nᵀ·b_k), so the point may slide in the plane
  /// through the target normal to n; for ICP markers, n is the surface normal at the closest point.
  Eigen::Vector3d plane_normal = Eigen::Vector3d::Zero();
  /// The 3x3 P with A_k = P·[w₁I₃ … w₄I₃]·S^k: I₃, or the projector n·nᵀ for a plane normal n.
  Eigen::Matrix3d metric() const {
    return plane_normal.isZero(0.0) ? Eigen::Matrix3d::Identity()
                                    : Eigen::Matrix3d(plane_normal * plane_normal.transpose());
  }
};

enum class ConstraintStatus {
  kOk,
  kInvalidMesh,         ///< a tet has a vertex outside [0, num_vertices), or num_vertices < 0
  kTetOutOfRange,       ///< a constraint's tet is not a row of tets
  kInvalidBarycentric,  ///< barycentric weights not finite or not summing to 1 (±1e-9); they need
                        ///< not be in [0, 1] (extrapolated points)
  kNonFiniteTarget,     ///< target has NaN or infinite coordinates
  kInvalidWeight,       ///< c_k is NaN, infinite or negative
  kInvalidNormal,       ///< plane_normal neither zero nor a unit vector (±1e-6)
  kIndexOutOfRange,     ///< (set_target / set_weight) no constraint with that index
};

const char* to_string(ConstraintStatus status);

/// Outcome of validating constraints; constraint names the first offending one.
struct ConstraintCheck {
  ConstraintStatus status = ConstraintStatus::kOk;
  std::optional<Eigen::Index> constraint;
  bool ok() const { return status == ConstraintStatus::kOk; }
  /// One line: the status and, if any, the offending constraint.
  std::string message() const;
};

/// A set of point constraints on a tet mesh: the A_k, b_k, c_k of appendix F, the energy, gradient
/// and Hessian. The Hessian Σ c_k A_kᵀA_k is assembled at create() into a pattern analysed once;
/// set_target and set_weight update b_k and c_k without allocation. Accessors taking a constraint
/// index k require 0 ≤ k < size() (not checked); set_target and set_weight check it.
class PointConstraints {
 public:
  /// num_vertices: n of the mesh; tets: #T by 4 (the mesh the points are embedded in).
  /// storage selects the full Hessian or its upper triangle. std::nullopt when a constraint is
  /// invalid; check (if not null) then says which and why.
  static std::optional<PointConstraints> create(
      Eigen::Index num_vertices, const common::TetIndices& tets,
      std::vector<PointConstraint> constraints,
      common::PatternStorage storage = common::PatternStorage::kFull,
      ConstraintCheck* check = nullptr);

  Eigen::Index size() const { return static_cast<Eigen::Index>(constraints_.size()); }
  Eigen::Index num_vertices() const { return num_vertices_; }
  Eigen::Index num_dofs() const { return 3 * num_vertices_; }
  const std::vector<PointConstraint>& constraints() const { return constraints_; }
  /// The four vertex indices of constraint k's tet (row k of a #constraints by 4 matrix).
  const Eigen::MatrixXi& vertices() const { return vertices_; }

  /// A_k (3 x 3n, eq. 53): 3x3 blocks w_a·P (P = metric(): I₃, or n·nᵀ for a plane normal) at the
  /// columns of the tet's vertices. Allocates.
  Eigen::SparseMatrix<double> selection_matrix(Eigen::Index k) const;
  /// All A_k stacked, [A_1; A_2; …] (3K x 3n), built at create() (the Z of eq. 12 before
  /// the √c_k scaling and J).
  const Eigen::SparseMatrix<double>& stacked_selection() const { return stacked_selection_; }
  /// b_k = −P·y_k (eq. 54).
  Eigen::Vector3d offset(Eigen::Index k) const {
    const PointConstraint& c = constraints_[index(k)];
    return -(c.metric() * c.target);
  }
  /// c_k.
  double weight(Eigen::Index k) const { return constraints_[index(k)].weight; }

  /// A_k x: current position of constraint k's material point (metres).
  Eigen::Vector3d position(Eigen::Index k, const Eigen::Ref<const Eigen::VectorXd>& x) const;
  /// A_k x + b_k = P·(position − y_k) (metres).
  Eigen::Vector3d residual(Eigen::Index k, const Eigen::Ref<const Eigen::VectorXd>& x) const;

  /// ½ Σ c_k ‖A_k x + b_k‖² (joules, eq. 55). x: 3n.
  double energy(const Eigen::Ref<const Eigen::VectorXd>& x) const;
  /// Σ c_k A_kᵀ(A_k x + b_k) (3n, newtons, eq. 56) written into gradient (size 3n). No allocation.
  void gradient(const Eigen::Ref<const Eigen::VectorXd>& x,
                Eigen::Ref<Eigen::VectorXd> gradient) const;
  /// Σ c_k A_kᵀA_k (3n x 3n, N/m; upper triangle only with kUpper storage). Independent of x.
  const Eigen::SparseMatrix<double>& hessian() const { return assembly_.matrix(); }

  /// Moves y_k (ICP re-targeting, §3.4). kIndexOutOfRange / kNonFiniteTarget leave it unchanged.
  ConstraintStatus set_target(Eigen::Index k, const Eigen::Vector3d& target);
  /// Changes c_k and re-assembles the Hessian values in place (O(K), no allocation).
  /// kIndexOutOfRange / kInvalidWeight leave everything unchanged.
  ConstraintStatus set_weight(Eigen::Index k, double weight);

 private:
  PointConstraints() = default;
  static std::size_t index(Eigen::Index k) { return static_cast<std::size_t>(k); }
  void assemble_hessian();

  Eigen::Index num_vertices_ = 0;
  std::vector<PointConstraint> constraints_;
  Eigen::MatrixXi vertices_;
  Eigen::SparseMatrix<double> stacked_selection_;
  common::SparseAssembly assembly_;
};

}  // namespace sinew::offline
