#include "offline/constraints/constraints.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <sstream>
#include <utility>

#include "common/fem/tet4.hpp"

namespace sinew::offline {

namespace {

constexpr double kBarycentricSumTolerance = 1e-9;

// Closest point to p on the triangle (a, b, c), by classifying p against the Voronoi regions of the
// vertices, edges and face (barycentric tests with dot products only; no division unless needed).
Eigen::Vector3d closest_point_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                          const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a;
  const Eigen::Vector3d ac = c - a;
  const Eigen::Vector3d ap = p - a;
  const double d1 = ab.dot(ap);
  const double d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return a;

  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp);
  const double d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return b;

  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return a + (d1 / (d1 - d3)) * ab;

  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp);
  const double d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return c;

  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return a + (d2 / (d2 - d6)) * ac;

  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0) {
    return b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b);
  }
  const double inv = 1.0 / (va + vb + vc);
  return a + ab * (vb * inv) + ac * (vc * inv);
}

double box_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& lo,
                    const Eigen::Vector3d& hi) {
  const Eigen::Vector3d outside = (lo - p).cwiseMax(p - hi).cwiseMax(0.0);
  return outside.norm();
}

Eigen::Vector4d barycentric(const Eigen::Matrix<double, 3, 4>& X, const Eigen::Matrix3d& Dm_inv,
                            const Eigen::Vector3d& p) {
  Eigen::Vector4d w;
  w.tail<3>() = Dm_inv * (p - X.col(0));
  w[0] = 1.0 - w.tail<3>().sum();
  return w;
}

}  // namespace

Eigen::Vector3d embedded_position(const common::TetIndices& tets, const EmbeddedPoint& p,
                                  const Eigen::Ref<const Eigen::VectorXd>& x) {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  for (int a = 0; a < 4; ++a) position += p.weights[a] * x.segment<3>(3 * tets(p.tet, a));
  return position;
}

std::optional<std::string> TetPointLocatorOptions::validate() const {
  std::ostringstream s;
  if (!(inside_tolerance >= 0.0 && inside_tolerance < 0.1)) {
    s << "inside_tolerance = " << inside_tolerance << " must be in [0, 0.1)";
    return s.str();
  }
  if (!(max_outside_distance >= 0.0)) {
    s << "max_outside_distance = " << max_outside_distance << " must be >= 0 (infinity: no limit)";
    return s.str();
  }
  if (!(degeneracy_tolerance >= 0.0 && degeneracy_tolerance < 0.1)) {
    s << "degeneracy_tolerance = " << degeneracy_tolerance << " must be in [0, 0.1)";
    return s.str();
  }
  return std::nullopt;
}

const char* to_string(EmbeddingStatus status) {
  switch (status) {
    case EmbeddingStatus::kInside:
      return "inside";
    case EmbeddingStatus::kOutside:
      return "outside (nearest tet)";
    case EmbeddingStatus::kTooFar:
      return "too far from the mesh";
    case EmbeddingStatus::kNonFinite:
      return "non-finite point";
  }
  return "unknown";
}

std::optional<TetPointLocator> TetPointLocator::create(
    const Eigen::Ref<const Eigen::MatrixXd>& rest_positions, const common::TetIndices& tets,
    const TetPointLocatorOptions& options, common::TetMeshCheck* check) {
  common::TetMeshCheck result;
  if (options.validate()) {
    result.status = common::TetMeshStatus::kInvalidOptions;
  } else {
    result = common::check_tet_mesh(rest_positions, tets, options.degeneracy_tolerance);
  }
  if (check) *check = result;
  if (!result.ok()) return std::nullopt;

  TetPointLocator locator(options);
  locator.tets_.resize(static_cast<std::size_t>(tets.rows()));
  for (Eigen::Index t = 0; t < tets.rows(); ++t) {
    Tet& tet = locator.tets_[static_cast<std::size_t>(t)];
    for (int a = 0; a < 4; ++a) tet.X.col(a) = rest_positions.row(tets(t, a)).transpose();
    tet.Dm_inv = common::edge_matrix(tet.X).inverse();
    tet.box_min = tet.X.rowwise().minCoeff();
    tet.box_max = tet.X.rowwise().maxCoeff();
  }
  return locator;
}

Embedding TetPointLocator::locate(const Eigen::Vector3d& point) const {
  Embedding result;
  if (!point.allFinite()) return result;  // kNonFinite

  double best = std::numeric_limits<double>::infinity();
  Eigen::Index best_tet = -1;
  Eigen::Vector3d best_closest = point;
  for (std::size_t t = 0; t < tets_.size(); ++t) {
    const Tet& tet = tets_[t];
    if (box_distance(point, tet.box_min, tet.box_max) > best) continue;
    const Eigen::Vector4d w = barycentric(tet.X, tet.Dm_inv, point);
    if (w.minCoeff() >= -options_.inside_tolerance) {
      result.status = EmbeddingStatus::kInside;
      result.point = {static_cast<Eigen::Index>(t), w};
      result.distance = 0.0;
      return result;
    }
    // Outside this tet: its closest point lies on one of the four faces.
    static constexpr int kFaces[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
    for (const auto& f : kFaces) {
      const Eigen::Vector3d q =
          closest_point_on_triangle(point, tet.X.col(f[0]), tet.X.col(f[1]), tet.X.col(f[2]));
      const double d = (q - point).norm();
      if (d < best) {
        best = d;
        best_tet = static_cast<Eigen::Index>(t);
        best_closest = q;
      }
    }
  }
  if (best_tet < 0 || !(best <= options_.max_outside_distance)) {
    result.status = EmbeddingStatus::kTooFar;
    result.distance = best;
    return result;
  }
  const Tet& tet = tets_[static_cast<std::size_t>(best_tet)];
  result.status = EmbeddingStatus::kOutside;
  result.distance = best;
  result.point.tet = best_tet;
  if (options_.outside_policy == OutsidePointPolicy::kExtrapolate) {
    result.point.weights = barycentric(tet.X, tet.Dm_inv, point);
  } else {
    // The closest point is on the tet's boundary: clear round-off negatives, renormalise.
    Eigen::Vector4d w = barycentric(tet.X, tet.Dm_inv, best_closest).cwiseMax(0.0);
    result.point.weights = w / w.sum();
  }
  return result;
}

const char* to_string(ConstraintKind kind) {
  switch (kind) {
    case ConstraintKind::kAttachment:
      return "attachment";
    case ConstraintKind::kLandmark:
      return "landmark";
    case ConstraintKind::kIcpMarker:
      return "ICP marker";
  }
  return "unknown";
}

const char* to_string(ConstraintStatus status) {
  switch (status) {
    case ConstraintStatus::kOk:
      return "ok";
    case ConstraintStatus::kInvalidMesh:
      return "invalid mesh (vertex index out of range)";
    case ConstraintStatus::kTetOutOfRange:
      return "tet index out of range";
    case ConstraintStatus::kInvalidBarycentric:
      return "barycentric weights not finite or not summing to 1";
    case ConstraintStatus::kNonFiniteTarget:
      return "non-finite target";
    case ConstraintStatus::kInvalidWeight:
      return "weight c_k not finite and >= 0";
    case ConstraintStatus::kInvalidNormal:
      return "plane normal neither zero nor of unit length";
    case ConstraintStatus::kIndexOutOfRange:
      return "no constraint with that index";
  }
  return "unknown";
}

std::string ConstraintCheck::message() const {
  std::ostringstream s;
  s << to_string(status);
  if (constraint) s << " (constraint " << *constraint << ")";
  return s.str();
}

std::optional<PointConstraints> PointConstraints::create(Eigen::Index num_vertices,
                                                         const common::TetIndices& tets,
                                                         std::vector<PointConstraint> constraints,
                                                         common::PatternStorage storage,
                                                         ConstraintCheck* check) {
  ConstraintCheck result;
  const auto fail = [&](ConstraintStatus status, std::optional<Eigen::Index> k) {
    result = {status, k};
    if (check) *check = result;
    return std::nullopt;
  };
  if (num_vertices < 0 ||
      (tets.size() > 0 && (tets.minCoeff() < 0 || tets.maxCoeff() >= num_vertices))) {
    return fail(ConstraintStatus::kInvalidMesh, std::nullopt);
  }
  const Eigen::Index K = static_cast<Eigen::Index>(constraints.size());
  for (Eigen::Index k = 0; k < K; ++k) {
    const PointConstraint& c = constraints[static_cast<std::size_t>(k)];
    if (c.point.tet < 0 || c.point.tet >= tets.rows()) {
      return fail(ConstraintStatus::kTetOutOfRange, k);
    }
    if (!c.point.weights.allFinite() ||
        !(std::abs(c.point.weights.sum() - 1.0) <= kBarycentricSumTolerance)) {
      return fail(ConstraintStatus::kInvalidBarycentric, k);
    }
    if (!c.target.allFinite()) return fail(ConstraintStatus::kNonFiniteTarget, k);
    if (!std::isfinite(c.weight) || !(c.weight >= 0.0)) {
      return fail(ConstraintStatus::kInvalidWeight, k);
    }
    const double normal_length = c.plane_normal.norm();
    if (!(normal_length == 0.0 || std::abs(normal_length - 1.0) <= 1e-6)) {
      return fail(ConstraintStatus::kInvalidNormal, k);
    }
  }

  PointConstraints set;
  set.num_vertices_ = num_vertices;
  set.constraints_ = std::move(constraints);
  set.vertices_.resize(K, 4);
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(static_cast<std::size_t>(12 * K));
  for (Eigen::Index k = 0; k < K; ++k) {
    const PointConstraint& c = set.constraints_[static_cast<std::size_t>(k)];
    const EmbeddedPoint& p = c.point;
    set.vertices_.row(k) = tets.row(p.tet);
    const Eigen::Matrix3d metric = c.metric();
    for (int a = 0; a < 4; ++a) {
      for (int d = 0; d < 3; ++d) {
        for (int e = 0; e < 3; ++e) {
          if (metric(d, e) != 0.0) {
            entries.emplace_back(3 * k + d, 3 * tets(p.tet, a) + e, p.weights[a] * metric(d, e));
          }
        }
      }
    }
  }
  set.stacked_selection_.resize(3 * K, 3 * num_vertices);
  set.stacked_selection_.setFromTriplets(entries.begin(), entries.end());  // sums repeated vertices
  set.stacked_selection_.makeCompressed();

  // The Hessian's pattern: every constraint is a 4-vertex "element" (repeated vertices allowed).
  if (set.assembly_.analyse(set.vertices_, num_vertices, storage) != common::AssemblyStatus::kOk) {
    return fail(ConstraintStatus::kInvalidMesh, std::nullopt);
  }
  set.assemble_hessian();
  if (check) *check = result;
  return set;
}

void PointConstraints::assemble_hessian() {
  assembly_.set_zero();
  common::Matrix12d block;
  for (Eigen::Index k = 0; k < size(); ++k) {
    const PointConstraint& c = constraints_[index(k)];
    // c_k A_kᵀA_k restricted to the tet: c_k (w wᵀ ⊗ I₃).
    block.setZero();
    const Eigen::Matrix3d metric = c.metric();  // A_kᵀA_k's 3x3 blocks: w_a w_b PᵀP = w_a w_b P
    for (int a = 0; a < 4; ++a) {
      for (int b = 0; b < 4; ++b) {
        const double value = c.weight * c.point.weights[a] * c.point.weights[b];
        block.block<3, 3>(3 * a, 3 * b) = value * metric;
      }
    }
    assembly_.add_element_matrix(k, block);
  }
}

Eigen::SparseMatrix<double> PointConstraints::selection_matrix(Eigen::Index k) const {
  std::vector<Eigen::Triplet<double>> entries;
  const PointConstraint& c = constraints_[index(k)];
  const Eigen::Matrix3d metric = c.metric();
  for (int a = 0; a < 4; ++a) {
    for (int d = 0; d < 3; ++d) {
      for (int e = 0; e < 3; ++e) {
        if (metric(d, e) != 0.0) {
          entries.emplace_back(d, 3 * vertices_(k, a) + e, c.point.weights[a] * metric(d, e));
        }
      }
    }
  }
  Eigen::SparseMatrix<double> A(3, num_dofs());
  A.setFromTriplets(entries.begin(), entries.end());
  return A;
}

Eigen::Vector3d PointConstraints::position(Eigen::Index k,
                                           const Eigen::Ref<const Eigen::VectorXd>& x) const {
  const EmbeddedPoint& p = constraints_[index(k)].point;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  for (int a = 0; a < 4; ++a) position += p.weights[a] * x.segment<3>(3 * vertices_(k, a));
  return position;
}

Eigen::Vector3d PointConstraints::residual(Eigen::Index k,
                                           const Eigen::Ref<const Eigen::VectorXd>& x) const {
  const PointConstraint& c = constraints_[index(k)];
  return c.metric() * (position(k, x) - c.target);
}

double PointConstraints::energy(const Eigen::Ref<const Eigen::VectorXd>& x) const {
  double total = 0.0;
  for (Eigen::Index k = 0; k < size(); ++k) {
    total += 0.5 * constraints_[index(k)].weight * residual(k, x).squaredNorm();
  }
  return total;
}

void PointConstraints::gradient(const Eigen::Ref<const Eigen::VectorXd>& x,
                                Eigen::Ref<Eigen::VectorXd> gradient) const {
  gradient.setZero();
  for (Eigen::Index k = 0; k < size(); ++k) {
    const PointConstraint& c = constraints_[index(k)];
    // A_kᵀ(A_k x + b_k) = Sᵀ·P·residual, and residual is already P(·) (P a projector or I).
    const Eigen::Vector3d r = c.weight * residual(k, x);
    for (int a = 0; a < 4; ++a) gradient.segment<3>(3 * vertices_(k, a)) += c.point.weights[a] * r;
  }
}

ConstraintStatus PointConstraints::set_target(Eigen::Index k, const Eigen::Vector3d& target) {
  if (k < 0 || k >= size()) return ConstraintStatus::kIndexOutOfRange;
  if (!target.allFinite()) return ConstraintStatus::kNonFiniteTarget;
  constraints_[index(k)].target = target;
  return ConstraintStatus::kOk;
}

ConstraintStatus PointConstraints::set_weight(Eigen::Index k, double weight) {
  if (k < 0 || k >= size()) return ConstraintStatus::kIndexOutOfRange;
  if (!std::isfinite(weight) || !(weight >= 0.0)) return ConstraintStatus::kInvalidWeight;
  constraints_[index(k)].weight = weight;
  assemble_hessian();
  return ConstraintStatus::kOk;
}

}  // namespace sinew::offline
