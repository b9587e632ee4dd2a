#include "common/fem/tet_mesh_elasticity.hpp"

#include <cmath>
#include <sstream>

namespace sinew::common {

namespace {

Matrix3x4d rest_tet(const Eigen::Ref<const Eigen::MatrixXd>& rest_positions, const TetIndices& tets,
                    Eigen::Index t) {
  Matrix3x4d X;
  for (int a = 0; a < 4; ++a) X.col(a) = rest_positions.row(tets(t, a)).transpose();
  return X;
}

}  // namespace

std::optional<std::string> TetMeshElasticityOptions::validate() const {
  if (!(degeneracy_tolerance >= 0.0 && degeneracy_tolerance < 0.1)) {
    std::ostringstream s;
    s << "degeneracy_tolerance = " << degeneracy_tolerance << " must be in [0, 0.1)";
    return s.str();
  }
  return std::nullopt;
}

const char* to_string(TetMeshStatus status) {
  switch (status) {
    case TetMeshStatus::kOk:
      return "ok";
    case TetMeshStatus::kInvalidOptions:
      return "invalid options";
    case TetMeshStatus::kInvalidShape:
      return "rest positions are not #V by 3";
    case TetMeshStatus::kIndexOutOfRange:
      return "vertex index out of range";
    case TetMeshStatus::kNonFinite:
      return "non-finite rest position";
    case TetMeshStatus::kDegenerateTet:
      return "degenerate rest tet";
    case TetMeshStatus::kInvertedTet:
      return "inverted rest tet";
  }
  return "unknown";
}

std::string TetMeshCheck::message() const {
  std::ostringstream s;
  s << to_string(status);
  if (tet) s << " (tet " << *tet << ")";
  return s.str();
}

TetMeshCheck check_tet_mesh(const Eigen::Ref<const Eigen::MatrixXd>& rest_positions,
                            const TetIndices& tets, double degeneracy_tolerance) {
  TetMeshCheck check;
  if (rest_positions.cols() != 3) {
    check.status = TetMeshStatus::kInvalidShape;
    return check;
  }
  for (Eigen::Index t = 0; t < tets.rows(); ++t) {
    if (tets.row(t).minCoeff() < 0 || tets.row(t).maxCoeff() >= rest_positions.rows()) {
      check = {TetMeshStatus::kIndexOutOfRange, t};
      return check;
    }
  }
  for (Eigen::Index t = 0; t < tets.rows(); ++t) {
    switch (make_tet4_rest(rest_tet(rest_positions, tets, t), degeneracy_tolerance).status) {
      case Tet4Status::kValid:
        break;
      case Tet4Status::kInverted:
        return {TetMeshStatus::kInvertedTet, t};
      case Tet4Status::kDegenerate:
        return {TetMeshStatus::kDegenerateTet, t};
      case Tet4Status::kNonFinite:
        return {TetMeshStatus::kNonFinite, t};
    }
  }
  return check;
}

std::optional<TetMeshElasticity> TetMeshElasticity::create(
    const Eigen::Ref<const Eigen::MatrixXd>& rest_positions, const TetIndices& tets,
    const StableNeoHookean& material, const TetMeshElasticityOptions& options,
    TetMeshCheck* check) {
  TetMeshCheck result;
  if (options.validate()) {
    result.status = TetMeshStatus::kInvalidOptions;
  } else {
    result = check_tet_mesh(rest_positions, tets, options.degeneracy_tolerance);
  }
  if (check) *check = result;
  if (!result.ok()) return std::nullopt;

  TetMeshElasticity mesh(material, options);
  mesh.num_vertices_ = rest_positions.rows();
  mesh.tets_ = tets;
  mesh.rest_.reserve(static_cast<std::size_t>(tets.rows()));
  for (Eigen::Index t = 0; t < tets.rows(); ++t) {
    mesh.rest_.push_back(
        make_tet4_rest(rest_tet(rest_positions, tets, t), options.degeneracy_tolerance));
  }
  if (mesh.assembly_.analyse(tets, mesh.num_vertices_, options.storage) != AssemblyStatus::kOk) {
    if (check) *check = {TetMeshStatus::kIndexOutOfRange, mesh.assembly_.bad_element()};
    return std::nullopt;
  }
  return mesh;
}

Matrix3x4d TetMeshElasticity::tet_positions(Eigen::Index t,
                                            const Eigen::Ref<const Eigen::VectorXd>& x) const {
  Matrix3x4d positions;
  for (int a = 0; a < 4; ++a) positions.col(a) = x.segment<3>(3 * tets_(t, a));
  return positions;
}

double TetMeshElasticity::energy(const Eigen::Ref<const Eigen::VectorXd>& x) const {
  double total = 0.0;
  for (Eigen::Index t = 0; t < num_tets(); ++t) {
    total += tet_elastic_energy(material_, rest_[static_cast<std::size_t>(t)], tet_positions(t, x));
  }
  return total;
}

void TetMeshElasticity::gradient(const Eigen::Ref<const Eigen::VectorXd>& x,
                                 Eigen::Ref<Eigen::VectorXd> gradient) const {
  gradient.setZero();
  Vector12d element_gradient;
  for (Eigen::Index t = 0; t < num_tets(); ++t) {
    evaluate_tet_elastic(material_, rest_[static_cast<std::size_t>(t)], tet_positions(t, x),
                         nullptr, &element_gradient, nullptr);
    assembly_.add_element_vector(t, element_gradient, gradient);
  }
}

const Eigen::SparseMatrix<double>& TetMeshElasticity::hessian(
    const Eigen::Ref<const Eigen::VectorXd>& x) {
  assembly_.set_zero();
  Matrix12d element_hessian;
  for (Eigen::Index t = 0; t < num_tets(); ++t) {
    evaluate_tet_elastic(material_, rest_[static_cast<std::size_t>(t)], tet_positions(t, x),
                         nullptr, nullptr, &element_hessian, options_.projection);
    assembly_.add_element_matrix(t, element_hessian);
  }
  return assembly_.matrix();
}

}  // namespace sinew::common
