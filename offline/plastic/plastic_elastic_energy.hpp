#pragma once
/// Elastic energy under plastic strain (seed 003, eq. 1; derivatives appendix B, eqs. 32–44):
///   E(s, x) = V(Fp)·ψ(F(x)·Fp⁻¹),   V(Fp) = det(Fp)·V₀,   Fp = Fp(s) (eq. 2),
/// per tet, and its assembly over a tet mesh: E, f_e = ∂E/∂x (3n; the paper's "elastic forces" are
/// this gradient, eq. 1), K = ∂²E/∂x² (3n x 3n), ∂f_e/∂s = ∂²E/∂x∂s (3n x 6m) and ∂E/∂s (6m).
///
/// It composes the separate concepts: element kinematics (common/fem/tet4.hpp), the material
/// (common/material/stable_neo_hookean.hpp), the plastic model (offline/plastic/plastic_strain.hpp)
/// and the assembly into patterns analysed once (common/fem/sparse_assembly.hpp).
///
/// Layouts: x is vertex-major (3n, [x0, y0, z0, x1, ...], metres; 12 element dofs likewise), s is
/// tet-major (6m, tet t owns s[6t .. 6t+5], offline/plastic/plastic_strain.hpp). Since Fe =
/// Ds·(Dm⁻¹Fp⁻¹), ∂vec(Fe)/∂x = (Fp⁻ᵀ ⊗ I₃)·dFdx is the dF/dx of a tet with "rest inverse"
/// Dm⁻¹Fp⁻¹.

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <optional>
#include <string>
#include <vector>

#include "common/fem/sparse_assembly.hpp"
#include "common/fem/tet4.hpp"
#include "common/fem/tet_mesh_elasticity.hpp"
#include "common/material/stable_neo_hookean.hpp"
#include "offline/plastic/plastic_strain.hpp"

namespace sinew::offline {

using Matrix12x6d = Eigen::Matrix<double, 12, 6>;

/// Where evaluate_plastic_tet writes; a null pointer means "not needed" (and is not computed).
struct PlasticTetOutputs {
  double* energy = nullptr;                 ///< E, joules
  common::Vector12d* gradient_x = nullptr;  ///< ∂E/∂x (12), newtons (eq. 32)
  Vector6d* gradient_s = nullptr;           ///< ∂E/∂s (6), joules (eq. 33, times Y)
  common::Matrix12d* hessian_xx = nullptr;  ///< ∂²E/∂x² (12x12), newtons per metre (eq. 36)
  /// ∂²E/∂x∂s (12x6): (i, k) = ∂²E/∂x_i∂s_k, i.e. ∂(gradient_x)/∂s (eqs. 37–39, times Y).
  Matrix12x6d* hessian_xs = nullptr;
  Matrix6d* hessian_ss = nullptr;  ///< ∂²E/∂s² (6x6), joules (eqs. 40–44, times Y on both sides)
};

/// E and any of its derivatives for one tet: rest data (valid or inverted; V₀ = |rest.volume|),
/// plastic strain s (6) and current positions (columns x0..x3, metres). projection applies to
/// hessian_xx only (kNone is the exact Hessian). Returns the status of Fp(s): when it is not
/// invertible (kSingular, kNonFinite) every requested output is set to NaN. kNotPositiveDefinite
/// still gives consistent values and derivatives (with V = det Fp·V₀ possibly ≤ 0). No allocation.
PlasticStrainStatus evaluate_plastic_tet(
    const common::StableNeoHookean& material, const common::Tet4Rest& rest, const Vector6d& s,
    const common::Matrix3x4d& positions, const PlasticTetOutputs& outputs,
    common::HessianProjection projection = common::HessianProjection::kNone);

/// ∂vec(Fe)/∂x (9x12) for Fe = F·Fp⁻¹: the dF/dx of common/fem/tet4.hpp with Dm⁻¹ → Dm⁻¹Fp⁻¹.
common::Matrix9x12d elastic_deformation_gradient_jacobian(const common::Tet4Rest& rest,
                                                          const Eigen::Matrix3d& Fp_inv);

struct PlasticElasticEnergyOptions {
  /// Per-element PSD projection of K = ∂²E/∂x² only (∂f_e/∂s, ∂E/∂s are always exact). kNone for
  /// derivative checks and the Gauss–Newton Jacobian (eq. 10); a projection for robust Newton
  /// equilibrium solves.
  common::HessianProjection projection = common::HessianProjection::kNone;
  /// Store all of K, or its upper triangle only (half the memory, for Cholesky solvers).
  common::PatternStorage storage = common::PatternStorage::kFull;
  /// A rest tet is degenerate when |6V₀| ≤ tolerance·(longest edge)³; in [0, 0.1).
  double degeneracy_tolerance = 1e-10;

  /// Empty when valid; otherwise one line naming the field, its value and the constraint.
  std::optional<std::string> validate() const;
};

/// Which quantities PlasticElasticEnergy::evaluate assembles.
struct PlasticEnergyRequest {
  bool energy = true;           ///< E
  bool gradient_x = false;      ///< f_e = ∂E/∂x (3n)
  bool gradient_s = false;      ///< ∂E/∂s (6m)
  bool stiffness = false;       ///< K = ∂²E/∂x² (3n x 3n, sparse)
  bool force_jacobian = false;  ///< ∂f_e/∂s = ∂²E/∂x∂s (3n x 6m, sparse)

  /// Everything.
  static PlasticEnergyRequest all() { return {true, true, true, true, true}; }
};

enum class PlasticEvaluationStatus {
  kOk,                     ///< every requested output is valid
  kNotPositiveDefinite,    ///< outputs valid, but some tet's Fp has a negative eigenvalue
  kSingularPlasticStrain,  ///< some tet's Fp is singular: outputs are not valid
  kNonFinite,              ///< NaN or infinity in s or x (or in a result): outputs are not valid
  kInvalidSize,            ///< s is not 6m or x is not 3n: nothing was evaluated
};

const char* to_string(PlasticEvaluationStatus status);

/// Outcome of PlasticElasticEnergy::evaluate; tet names the first tet with the reported problem.
struct PlasticEvaluation {
  PlasticEvaluationStatus status = PlasticEvaluationStatus::kInvalidSize;
  std::optional<Eigen::Index> tet;

  /// True when the requested outputs may be used (kOk or kNotPositiveDefinite).
  bool valid() const {
    return status == PlasticEvaluationStatus::kOk ||
           status == PlasticEvaluationStatus::kNotPositiveDefinite;
  }
  /// One line: the status and, if any, the offending tet.
  std::string message() const;
};

/// The plastic elastic energy of a whole tet mesh. Rest data, the pattern of K (through
/// common::SparseAssembly) and the pattern of ∂f_e/∂s are built once by create(); evaluate() then
/// only overwrites values: no allocation, no search.
class PlasticElasticEnergy {
 public:
  /// rest_positions: #V by 3 (metres); tets: #T by 4, right-handed. Returns std::nullopt when the
  /// options or the mesh are invalid; check (if not null) then says why (common::check_tet_mesh).
  static std::optional<PlasticElasticEnergy> create(
      const Eigen::Ref<const Eigen::MatrixXd>& rest_positions, const common::TetIndices& tets,
      const common::StableNeoHookean& material, const PlasticElasticEnergyOptions& options = {},
      common::TetMeshCheck* check = nullptr);

  Eigen::Index num_vertices() const { return num_vertices_; }
  Eigen::Index num_tets() const { return tets_.rows(); }
  Eigen::Index num_dofs() const { return 3 * num_vertices_; }                        ///< 3n
  Eigen::Index num_plastic_dofs() const { return kPlasticStrainSize * num_tets(); }  ///< 6m
  const common::TetIndices& tets() const { return tets_; }
  const std::vector<common::Tet4Rest>& rest() const { return rest_; }
  const common::StableNeoHookean& material() const { return material_; }
  const PlasticElasticEnergyOptions& options() const { return options_; }
  /// Rest positions as the 3n dof vector (x̄ of the paper).
  const Eigen::VectorXd& rest_dofs() const { return rest_dofs_; }

  /// Positions of the four vertices of tet t (columns) taken from the dof vector x (3n).
  common::Matrix3x4d tet_positions(Eigen::Index t,
                                   const Eigen::Ref<const Eigen::VectorXd>& x) const;

  /// Assembles the requested quantities at plastic state s (6m) and positions x (3n, metres) into
  /// this object's storage (read them with the accessors below). Stops at the first tet whose Fp
  /// is singular or non-finite. No allocation.
  PlasticEvaluation evaluate(const Eigen::Ref<const Eigen::VectorXd>& s,
                             const Eigen::Ref<const Eigen::VectorXd>& x,
                             const PlasticEnergyRequest& request);

  /// Results of the last evaluate() that requested them; their arrays never move, sizes are fixed.
  double energy() const { return energy_; }                          ///< joules
  const Eigen::VectorXd& gradient_x() const { return gradient_x_; }  ///< f_e, 3n, newtons
  const Eigen::VectorXd& gradient_s() const { return gradient_s_; }  ///< ∂E/∂s, 6m, joules
  /// K (3n x 3n, N/m; upper triangle only with kUpper storage), with the options' projection.
  const Eigen::SparseMatrix<double>& stiffness() const { return assembly_.matrix(); }
  /// ∂f_e/∂s (3n x 6m, N): column 6t+k holds the 12 entries of tet t's ∂(∂E_t/∂x)/∂s_k.
  const Eigen::SparseMatrix<double>& force_jacobian() const { return force_jacobian_; }

 private:
  PlasticElasticEnergy(const common::StableNeoHookean& material,
                       const PlasticElasticEnergyOptions& options)
      : material_(material), options_(options) {}

  common::StableNeoHookean material_;
  PlasticElasticEnergyOptions options_;
  Eigen::Index num_vertices_ = 0;
  common::TetIndices tets_;
  std::vector<common::Tet4Rest> rest_;
  Eigen::VectorXd rest_dofs_;
  common::SparseAssembly assembly_;  // K
  Eigen::SparseMatrix<double> force_jacobian_;
  // force_jacobian_scatter_(t, a): offset of vertex a's 3 rows within each of tet t's columns
  // (0, 3, 6 or 9: the rank of that vertex index among the tet's four).
  Eigen::Matrix<int, Eigen::Dynamic, 4> force_jacobian_scatter_;
  double energy_ = 0.0;
  Eigen::VectorXd gradient_x_;
  Eigen::VectorXd gradient_s_;
};

}  // namespace sinew::offline
