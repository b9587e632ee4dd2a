#pragma once
/// Mass of linear tetrahedra (seed 002, "Integrating the Mass Matrix"): the consistent mass
/// M₀ = ∫ ρ NᵀN dΩ with N(X) = [φ0 I, φ1 I, φ2 I, φ3 I] (3x12), whose 3x3 blocks are
/// ρ ∫ φ_a φ_b dΩ · I = ρV/10 · I for a = b and ρV/20 · I for a ≠ b; and the lumped (row-sum)
/// mass ρV/4 per vertex. Dofs are vertex-major (common/fem/tet4.hpp,
/// common/fem/sparse_assembly.hpp).

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <optional>

#include "common/fem/sparse_assembly.hpp"
#include "common/fem/tet4.hpp"

namespace sinew::common {

/// Consistent mass matrix of one tetrahedron (12x12, kilograms) for density ρ (kg/m³) and rest
/// volume V (m³; its absolute value is used). Its entries sum to 3ρ|V| (ρ|V| per direction).
Matrix12d consistent_mass_matrix(double density, double volume);

/// Lumped masses of the four vertices of one tetrahedron, ρ|V|/4 each (kilograms).
Eigen::Vector4d lumped_vertex_masses(double density, double volume);

/// Global consistent mass matrix (3#V by 3#V, kilograms) of a tet mesh with uniform density ρ:
/// rest_positions is #V by 3 (metres), tets #T by 4. Degenerate tets contribute (almost) nothing;
/// inverted ones their |V|. std::nullopt when a tet index is out of range.
std::optional<Eigen::SparseMatrix<double>> assemble_consistent_mass(
    const Eigen::Ref<const Eigen::MatrixXd>& rest_positions, const TetIndices& tets, double density,
    PatternStorage storage = PatternStorage::kFull);

/// Global lumped masses per vertex (#V, kilograms): each tet adds ρ|V|/4 to its four vertices.
/// (Per dof, repeat each entry three times.) std::nullopt when a tet index is out of range.
std::optional<Eigen::VectorXd> assemble_lumped_mass(
    const Eigen::Ref<const Eigen::MatrixXd>& rest_positions, const TetIndices& tets,
    double density);

}  // namespace sinew::common
