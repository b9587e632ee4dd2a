#pragma once
/// Elastic energy of a whole tet mesh, E(x) = Σ_t V_t ψ(F_t(x)) (seed 002, "Potential Energy for
/// a Bunny"), its gradient and its sparse Hessian. It composes the three separate concepts:
/// element kinematics (common/fem/tet4.hpp), the material (common/material/stable_neo_hookean.hpp)
/// and assembly into a pattern analysed once (common/fem/sparse_assembly.hpp).
///
/// Current positions are the 3#V dof vector x = [x0, y0, z0, x1, ...] (metres), see to_dof_vector.

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <optional>
#include <string>
#include <vector>

#include "common/fem/sparse_assembly.hpp"
#include "common/fem/tet4.hpp"
#include "common/material/stable_neo_hookean.hpp"

namespace sinew::common {

struct TetMeshElasticityOptions {
  /// Per-element PSD projection of the Hessian (kNone: the exact Hessian, for derivative checks
  /// and for solvers that handle indefiniteness; kProjectDPdF: cheapest convex approximation).
  HessianProjection projection = HessianProjection::kNone;
  /// Store the full Hessian or its upper triangle only (half the memory, for Cholesky solvers).
  PatternStorage storage = PatternStorage::kFull;
  /// A rest tet is degenerate when |6V| ≤ tolerance · (longest edge)³; in [0, 0.1).
  double degeneracy_tolerance = 1e-10;

  /// Empty when valid; otherwise one line naming the field, its value and the constraint.
  std::optional<std::string> validate() const;
};

enum class TetMeshStatus {
  kOk,
  kInvalidOptions,   ///< TetMeshElasticityOptions::validate() failed
  kInvalidShape,     ///< rest_positions is not #V by 3
  kIndexOutOfRange,  ///< a tet refers to a vertex outside [0, #V)
  kNonFinite,        ///< a rest position is NaN or infinite
  kDegenerateTet,    ///< a rest tet has (nearly) zero volume
  kInvertedTet,      ///< a rest tet has negative volume (left-handed vertex order)
};

const char* to_string(TetMeshStatus status);

/// Result of checking a rest mesh; tet names the first offending tetrahedron when there is one.
struct TetMeshCheck {
  TetMeshStatus status = TetMeshStatus::kOk;
  std::optional<Eigen::Index> tet;
  bool ok() const { return status == TetMeshStatus::kOk; }
  /// One line: the status and, if any, the offending tet.
  std::string message() const;
};

/// Checks rest_positions (#V by 3, metres) and tets (#T by 4) for the problems above.
TetMeshCheck check_tet_mesh(const Eigen::Ref<const Eigen::MatrixXd>& rest_positions,
                            const TetIndices& tets, double degeneracy_tolerance = 1e-10);

class TetMeshElasticity {
 public:
  /// Precomputes the rest data of every tet and analyses the Hessian pattern once. Returns
  /// std::nullopt when the options or the mesh are invalid; check (if not null) then says why.
  static std::optional<TetMeshElasticity> create(
      const Eigen::Ref<const Eigen::MatrixXd>& rest_positions, const TetIndices& tets,
      const StableNeoHookean& material, const TetMeshElasticityOptions& options = {},
      TetMeshCheck* check = nullptr);

  Eigen::Index num_vertices() const { return num_vertices_; }
  Eigen::Index num_tets() const { return tets_.rows(); }
  Eigen::Index num_dofs() const { return 3 * num_vertices_; }
  const TetIndices& tets() const { return tets_; }
  const std::vector<Tet4Rest>& rest() const { return rest_; }
  const StableNeoHookean& material() const { return material_; }
  const TetMeshElasticityOptions& options() const { return options_; }

  /// Positions of the four vertices of tet t (columns) taken from the dof vector x (3#V).
  Matrix3x4d tet_positions(Eigen::Index t, const Eigen::Ref<const Eigen::VectorXd>& x) const;

  /// Elastic energy E(x) (joules); x has 3#V entries (metres).
  double energy(const Eigen::Ref<const Eigen::VectorXd>& x) const;

  /// Gradient ∂E/∂x (3#V, newtons) written into gradient (size 3#V). No allocation.
  void gradient(const Eigen::Ref<const Eigen::VectorXd>& x,
                Eigen::Ref<Eigen::VectorXd> gradient) const;

  /// Hessian ∂²E/∂x² (3#V by 3#V, newtons per metre; upper triangle only with kUpper storage),
  /// assembled in place into the pattern analysed by create(), with the options' projection.
  /// The returned reference stays valid (same arrays) across calls. No allocation.
  const Eigen::SparseMatrix<double>& hessian(const Eigen::Ref<const Eigen::VectorXd>& x);

 private:
  TetMeshElasticity(const StableNeoHookean& material, const TetMeshElasticityOptions& options)
      : material_(material), options_(options) {}

  StableNeoHookean material_;
  TetMeshElasticityOptions options_;
  Eigen::Index num_vertices_ = 0;
  TetIndices tets_;
  std::vector<Tet4Rest> rest_;
  SparseAssembly assembly_;
};

}  // namespace sinew::common
