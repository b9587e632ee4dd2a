#pragma once
/// A plane beam as a chain of beam elements: nodes 0..n−1 in the reference configuration
/// (a polyline: straight or curved, equal or unequal element lengths), one section and optional
/// pre-stress per element, and any subset of the 3n dofs (ux, uy, θ per node) fixed.
/// State vector u = [ux₀, uy₀, θ₀, …] (seed 000, eq. 1); current node i is at X_i + (ux_i, uy_i).

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "common/beam/beam_element.hpp"
#include "common/beam/block_tridiagonal.hpp"

namespace sinew::common {

/// Linear-elastic material and cross-section of a beam (seed 000 §3.1, A-8). Consistent units.
struct BeamMaterial {
  double E = 0.0;  ///< Young's modulus, > 0
  double G = 0.0;  ///< shear modulus, > 0
  double A = 0.0;  ///< cross-section area, > 0
  double I = 0.0;  ///< second moment of area, > 0

  BeamSection section() const { return {E * A, G * A, E * I}; }
  /// Empty when valid; otherwise one line naming the field, its value and the broken constraint.
  std::optional<std::string> validate() const;
};

enum class BeamDof : int { kUx = 0, kUy = 1, kTheta = 2 };

/// Plain description of a beam, checked by validate() before a BeamModel is built.
struct BeamDescription {
  Eigen::Matrix2Xd rest_positions;       ///< 2 x n reference node positions, n ≥ 2
  std::vector<BeamSection> sections;     ///< n − 1 element sections
  std::vector<BeamPrestress> prestress;  ///< empty (stress-free reference) or n − 1 entries
  std::vector<unsigned char> fixed;      ///< empty (free beam) or 3n flags, dof 3i + BeamDof

  /// A description with one material for every element and no fixed dof.
  static BeamDescription uniform(const Eigen::Matrix2Xd& rest_positions,
                                 const BeamMaterial& material);
  /// Marks dof `dof` of node `node` as fixed (allocates `fixed` on first use).
  void fix(int node, BeamDof dof);
  void clamp(int node);  ///< fixes ux, uy and θ

  /// Empty when valid; otherwise one line naming the node/element/field and what is wrong.
  std::optional<std::string> validate() const;
};

class BeamModel {
 public:
  /// Requires description.validate() to be empty (checked; an invalid description gives an
  /// empty model with num_nodes() == 0 and the reason in error()).
  explicit BeamModel(BeamDescription description);

  bool valid() const { return error_.empty(); }
  const std::string& error() const { return error_; }

  int num_nodes() const { return static_cast<int>(description_.rest_positions.cols()); }
  int num_elements() const { return static_cast<int>(references_.size()); }
  int num_dofs() const { return 3 * num_nodes(); }
  const BeamDescription& description() const { return description_; }
  const Eigen::Matrix2Xd& rest_positions() const { return description_.rest_positions; }
  const BeamElementReference& element(int e) const { return references_[e]; }
  /// 3n flags, 1 for fixed dofs (all zero for a free beam).
  const std::vector<unsigned char>& fixed_mask() const { return fixed_mask_; }
  int num_fixed_dofs() const;
  /// Total reference length Σ L₀ (a length scale for tolerances).
  double total_length() const { return total_length_; }
  /// Largest element bending stiffness EI (with total_length() gives the force scale EI/L²).
  double max_bending_stiffness() const { return max_EI_; }

  /// True when the fixed dofs leave no rigid motion of the reference configuration free
  /// (a free or under-constrained beam has a singular stiffness). Computed once at construction.
  bool rigid_motions_constrained() const { return rigid_motions_constrained_; }

  /// Strain energy, internal force p(u) (3n) and tangent K_T(u) (block-tridiagonal) summed over
  /// elements. Null outputs are skipped; outputs must be pre-sized; nothing is allocated.
  void evaluate(const Eigen::Ref<const Eigen::VectorXd>& u, double* energy,
                Eigen::Ref<Eigen::VectorXd>* internal_force, BlockTridiagonal* tangent) const;
  double energy(const Eigen::Ref<const Eigen::VectorXd>& u) const;
  Eigen::VectorXd internal_force(const Eigen::Ref<const Eigen::VectorXd>& u) const;

  /// Element e's 6 dofs out of the global vector.
  static Vector6d element_dofs(const Eigen::Ref<const Eigen::VectorXd>& u, int e) {
    return u.segment<6>(3 * e);
  }
  /// Current node positions X + (ux, uy), 2 x n.
  Eigen::Matrix2Xd current_positions(const Eigen::Ref<const Eigen::VectorXd>& u) const;

 private:
  BeamDescription description_;
  std::vector<BeamElementReference> references_;
  std::vector<unsigned char> fixed_mask_;
  double total_length_ = 0.0;
  double max_EI_ = 0.0;
  bool rigid_motions_constrained_ = false;
  std::string error_;

  bool compute_rigid_motions_constrained() const;
};

}  // namespace sinew::common
