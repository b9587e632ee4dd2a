#include "common/fem/mass.hpp"

#include <cmath>

namespace sinew::common {

namespace {

Matrix3x4d tet_vertices(const Eigen::Ref<const Eigen::MatrixXd>& rest_positions,
                        const TetIndices& tets, Eigen::Index t) {
  Matrix3x4d X;
  for (int a = 0; a < 4; ++a) X.col(a) = rest_positions.row(tets(t, a)).transpose();
  return X;
}

bool indices_in_range(const Eigen::Ref<const Eigen::MatrixXd>& rest_positions,
                      const TetIndices& tets) {
  return rest_positions.cols() == 3 &&
         (tets.size() == 0 || (tets.minCoeff() >= 0 && tets.maxCoeff() < rest_positions.rows()));
}

}  // namespace

Matrix12d consistent_mass_matrix(double density, double volume) {
  // Seed 002: ρ ∫ φ_a φ_b dΩ = 6ρV ∫∫∫ φ_a φ_b dφ = ρV/10 (a = b), ρV/20 (a ≠ b).
  const double m = density * std::abs(volume);
  Matrix12d M = Matrix12d::Zero();
  for (int a = 0; a < 4; ++a) {
    for (int b = 0; b < 4; ++b) {
      M.block<3, 3>(3 * a, 3 * b).diagonal().setConstant(a == b ? m / 10.0 : m / 20.0);
    }
  }
  return M;
}

Eigen::Vector4d lumped_vertex_masses(double density, double volume) {
  return Eigen::Vector4d::Constant(density * std::abs(volume) / 4.0);
}

std::optional<Eigen::SparseMatrix<double>> assemble_consistent_mass(
    const Eigen::Ref<const Eigen::MatrixXd>& rest_positions, const TetIndices& tets, double density,
    PatternStorage storage) {
  if (!indices_in_range(rest_positions, tets)) return std::nullopt;
  SparseAssembly assembly;
  if (assembly.analyse(tets, rest_positions.rows(), storage) != AssemblyStatus::kOk) {
    return std::nullopt;
  }
  assembly.set_zero();
  for (Eigen::Index t = 0; t < tets.rows(); ++t) {
    const double volume = signed_volume(tet_vertices(rest_positions, tets, t));
    assembly.add_element_matrix(t, consistent_mass_matrix(density, volume));
  }
  return assembly.matrix();
}

std::optional<Eigen::VectorXd> assemble_lumped_mass(
    const Eigen::Ref<const Eigen::MatrixXd>& rest_positions, const TetIndices& tets,
    double density) {
  if (!indices_in_range(rest_positions, tets)) return std::nullopt;
  Eigen::VectorXd masses = Eigen::VectorXd::Zero(rest_positions.rows());
  for (Eigen::Index t = 0; t < tets.rows(); ++t) {
    const Eigen::Vector4d m =
        lumped_vertex_masses(density, signed_volume(tet_vertices(rest_positions, tets, t)));
    for (int a = 0; a < 4; ++a) masses[tets(t, a)] += m[a];
  }
  return masses;
}

}  // namespace sinew::common
