#include "offline/separation/interpenetration.hpp"

#include <Eigen/Geometry>
#include <Eigen/SparseCore>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <sstream>
#include <utility>
#include <vector>

#include "common/detail/field_error.hpp"
#include "common/fem/tet4.hpp"
#include "common/timing.hpp"
#include "offline/constraints/constraints.hpp"
#include "offline/linalg/sparse_cholesky.hpp"
#include "offline/meshing/surface_closest_point.hpp"
#include "offline/plastic/plastic_elastic_energy.hpp"
#include "offline/plastic/plastic_strain.hpp"
#include "offline/plastic/plastic_strain_laplacian.hpp"

namespace sinew::offline {
namespace {

using Clock = std::chrono::steady_clock;

using common::seconds_since;

// Relative slack of the Armijo test for round-off in the total energy (as in equilibrium.cpp).
constexpr double kEnergyRoundoff = 1e-12;
// Weak spring of every free vertex to its input position, relative to μ·h: removes the rigid
// motions of a mesh that is active as a whole (a small organ), negligible against the elasticity.
constexpr double kAnchorStiffness = 1e-6;

template <class T>
std::string field_error(const char* field, T value, const char* constraint) {
  return common::detail::field_error("InterpenetrationOptions::", field, value,
                                     std::string("must be ") + constraint);
}

/// Positions as the vertex-major 3n dof vector.
Eigen::VectorXd dofs_of(const TetMesh& mesh) {
  const Eigen::Matrix<double, 3, Eigen::Dynamic> xt = mesh.vertices.transpose();
  return Eigen::Map<const Eigen::VectorXd>(xt.data(), xt.size());
}

double mean_edge_length(const TetMesh& mesh, double* sum, Eigen::Index* count) {
  static constexpr int kEdges[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
  for (Eigen::Index t = 0; t < mesh.tets.rows(); ++t) {
    for (const auto& e : kEdges)
      *sum +=
          (mesh.vertices.row(mesh.tets(t, e[0])) - mesh.vertices.row(mesh.tets(t, e[1]))).norm();
    *count += 6;
  }
  return *count > 0 ? *sum / static_cast<double>(*count) : 0.0;
}

/// One penetrating vertex: where the other surface is and which way is out.
struct Contact {
  int vertex = 0;                                     ///< in its own mesh
  double depth = 0.0;                                 ///< distance to the other boundary
  Eigen::Vector3d closest = Eigen::Vector3d::Zero();  ///< closest point on the other boundary
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();   ///< unit, from the vertex out of the other
  std::array<int, 3> face{};                          ///< the other mesh's closest boundary face
  Eigen::Vector3d weights = Eigen::Vector3d::Constant(1.0 / 3.0);  ///< of closest on face
};

/// Collision detection of the boundary vertices of one mesh against the volume of another.
class Detector {
 public:
  static std::optional<Detector> create(const TetMesh& mesh, const TetMesh& other) {
    if (mesh.tets.rows() == 0 || other.tets.rows() == 0) return std::nullopt;
    auto boundary = BoundarySurface::extract(mesh.vertices.rows(), mesh.tets);
    auto surface = SurfaceClosestPoint::create(other.vertices.rows(), other.tets);
    if (!boundary || !surface) return std::nullopt;
    Detector d;
    d.boundary_vertices_ = boundary->vertices();
    d.surface_ = std::make_unique<SurfaceClosestPoint>(std::move(*surface));
    return d;
  }

  const std::vector<int>& boundary_vertices() const { return boundary_vertices_; }

  /// The boundary vertices of mesh inside other, at their current positions.
  std::optional<std::vector<Contact>> detect(const TetMesh& mesh, const TetMesh& other) {
    std::vector<Contact> contacts;
    TetPointLocatorOptions locator_options;
    locator_options.max_outside_distance = 0.0;  // outside points need no nearest tet
    const Eigen::MatrixXd other_positions = other.vertices;
    auto locator = TetPointLocator::create(other_positions, other.tets, locator_options);
    if (!locator) return std::nullopt;
    if (surface_->update(dofs_of(other)) != SurfaceUpdateStatus::kOk) return std::nullopt;
    const Eigen::Vector3d lo = other.vertices.colwise().minCoeff().transpose();
    const Eigen::Vector3d hi = other.vertices.colwise().maxCoeff().transpose();
    const auto& triangles = surface_->boundary().triangles();
    for (const int v : boundary_vertices_) {
      const Eigen::Vector3d p = mesh.vertices.row(v).transpose();
      if ((p.array() < lo.array()).any() || (p.array() > hi.array()).any()) continue;
      if (locator->locate(p).status != EmbeddingStatus::kInside) continue;
      const SurfacePoint q = surface_->query(p);
      if (!q.ok()) return std::nullopt;
      Contact c;
      c.vertex = v;
      c.depth = q.distance;
      c.closest = q.point;
      c.weights = q.barycentric;
      for (int i = 0; i < 3; ++i) c.face[static_cast<std::size_t>(i)] = triangles(q.face, i);
      const Eigen::Vector3d a = other.vertices.row(c.face[0]).transpose();
      const Eigen::Vector3d b = other.vertices.row(c.face[1]).transpose();
      const Eigen::Vector3d d = other.vertices.row(c.face[2]).transpose();
      const Eigen::Vector3d face_normal = (b - a).cross(d - a);
      const double scale = (hi - lo).norm();
      // On (or within round-off of) the other surface the direction to the closest point is
      // meaningless: take the outward normal of the closest face instead.
      if (c.depth > 1e-9 * scale) {
        c.normal = (c.closest - p) / c.depth;
      } else if (face_normal.norm() > 0.0) {
        c.normal = face_normal.normalized();
      } else {
        continue;
      }
      contacts.push_back(c);
    }
    return contacts;
  }

 private:
  Detector() = default;
  std::vector<int> boundary_vertices_;
  std::unique_ptr<SurfaceClosestPoint> surface_;
};

double max_depth(const std::vector<Contact>& contacts) {
  double m = 0.0;
  for (const Contact& c : contacts) m = std::max(m, c.depth);
  return m;
}

/// Tets incident to each vertex.
std::vector<std::vector<int>> vertex_tets(const TetMesh& mesh) {
  std::vector<std::vector<int>> incident(static_cast<std::size_t>(mesh.vertices.rows()));
  for (Eigen::Index t = 0; t < mesh.tets.rows(); ++t)
    for (int a = 0; a < 4; ++a)
      incident[static_cast<std::size_t>(mesh.tets(t, a))].push_back(static_cast<int>(t));
  return incident;
}

/// The part of one mesh that may move: its topology, fixed for the whole call.
struct Region {
  std::vector<std::vector<int>> incident;    // vertex -> tets
  std::vector<std::vector<int>> neighbours;  // tet -> face-adjacent tets
  std::vector<char> seed_vertices;           // penetrating in some round
  std::vector<char> active;                  // per tet
  std::vector<char> free;                    // per vertex

  explicit Region(const TetMesh& mesh)
      : incident(vertex_tets(mesh)),
        neighbours(static_cast<std::size_t>(mesh.tets.rows())),
        seed_vertices(static_cast<std::size_t>(mesh.vertices.rows()), 0),
        active(static_cast<std::size_t>(mesh.tets.rows()), 0),
        free(static_cast<std::size_t>(mesh.vertices.rows()), 0) {
    const TetAdjacency adjacency = tet_face_adjacency(mesh.tets);
    for (Eigen::Index k = 0; k < adjacency.pairs.rows(); ++k) {
      neighbours[static_cast<std::size_t>(adjacency.pairs(k, 0))].push_back(adjacency.pairs(k, 1));
      neighbours[static_cast<std::size_t>(adjacency.pairs(k, 1))].push_back(adjacency.pairs(k, 0));
    }
  }

  /// Tets of the seed vertices grown by `rings` rings of face adjacency; free vertices are those
  /// all of whose tets are active.
  void grow(int rings) {
    for (std::size_t v = 0; v < seed_vertices.size(); ++v)
      if (seed_vertices[v] != 0)
        for (const int t : incident[v]) active[static_cast<std::size_t>(t)] = 1;
    // Rings from every active tet (the region only grows over the rounds).
    std::vector<int> front;
    for (std::size_t t = 0; t < active.size(); ++t)
      if (active[t] != 0) front.push_back(static_cast<int>(t));
    for (int ring = 0; ring < rings; ++ring) {
      std::vector<int> next;
      for (const int t : front) {
        for (const int n : neighbours[static_cast<std::size_t>(t)]) {
          if (active[static_cast<std::size_t>(n)] == 0) {
            active[static_cast<std::size_t>(n)] = 1;
            next.push_back(n);
          }
        }
      }
      front = std::move(next);
    }
    for (std::size_t v = 0; v < free.size(); ++v) {
      bool all = !incident[v].empty();
      for (const int t : incident[v]) all = all && active[static_cast<std::size_t>(t)] != 0;
      free[v] = all ? 1 : 0;
    }
  }

  Eigen::Index active_tets() const {
    return static_cast<Eigen::Index>(std::count(active.begin(), active.end(), 1));
  }
};

/// A one-sided vertex-face penalty: the vertex of one mesh must stay `gap` beyond the point with
/// barycentric `weights` on a boundary face of the other, along the frozen normal n:
///   g = nᵀ(x_v − Σ_i w_i x_{f_i}) − gap ≥ 0,  energy ½ c min(0, g)².
/// Both the vertex and the face move, each side in proportion to its compliance.
struct ContactPair {
  int mesh = 0;  ///< 0: the vertex is A's and the face B's; 1: the other way round
  int vertex = 0;
  std::array<int, 3> face{};
  Eigen::Vector3d weights = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  double gap = 0.0;
  double stiffness = 0.0;
};

/// Outcome of one contact solve round.
struct RoundResult {
  bool ok = false;
  int newton_iterations = 0;
  std::string failure;
};

/// The active tets of both meshes as one sub-mesh, vertices renumbered (A's first).
struct ContactSubMesh {
  std::vector<std::vector<int>> local;      // per mesh: vertex -> sub vertex (−1: not active)
  std::vector<std::pair<int, int>> global;  // sub vertex -> (mesh, vertex)
  Eigen::MatrixXd rest;                     // the input shapes' positions (the rest shape)
  Eigen::VectorXd x;                        // the current positions
  std::vector<char> is_free;
  common::TetIndices tets;
};

ContactSubMesh contact_sub_mesh(const TetMesh* const meshes[2], const TetMesh* const rests[2],
                                const Region* const regions[2]) {
  ContactSubMesh sub;
  std::vector<std::vector<int>>& local = sub.local;
  std::vector<std::pair<int, int>>& global = sub.global;
  local.resize(2);
  std::vector<std::array<int, 4>> sub_tets;
  for (int m = 0; m < 2; ++m) {
    local[static_cast<std::size_t>(m)].assign(static_cast<std::size_t>(meshes[m]->vertices.rows()),
                                              -1);
    auto& map = local[static_cast<std::size_t>(m)];
    for (Eigen::Index t = 0; t < meshes[m]->tets.rows(); ++t) {
      if (regions[m]->active[static_cast<std::size_t>(t)] == 0) continue;
      std::array<int, 4> tet{};
      for (int k = 0; k < 4; ++k) {
        const int v = meshes[m]->tets(t, k);
        if (map[static_cast<std::size_t>(v)] < 0) {
          map[static_cast<std::size_t>(v)] = static_cast<int>(global.size());
          global.emplace_back(m, v);
        }
        tet[static_cast<std::size_t>(k)] = map[static_cast<std::size_t>(v)];
      }
      sub_tets.push_back(tet);
    }
  }
  const auto n = static_cast<Eigen::Index>(global.size());
  Eigen::MatrixXd& rest = sub.rest;
  Eigen::VectorXd& x = sub.x;
  std::vector<char>& is_free = sub.is_free;
  rest.resize(n, 3);
  x.resize(3 * n);
  is_free.assign(static_cast<std::size_t>(n), 0);
  for (Eigen::Index i = 0; i < n; ++i) {
    const auto [m, v] = global[static_cast<std::size_t>(i)];
    rest.row(i) = rests[m]->vertices.row(v);
    x.segment<3>(3 * i) = meshes[m]->vertices.row(v).transpose();
    is_free[static_cast<std::size_t>(i)] = regions[m]->free[static_cast<std::size_t>(v)];
  }
  common::TetIndices& tets = sub.tets;
  tets.resize(static_cast<Eigen::Index>(sub_tets.size()), 4);
  for (std::size_t t = 0; t < sub_tets.size(); ++t)
    for (int k = 0; k < 4; ++k)
      tets(static_cast<Eigen::Index>(t), k) = sub_tets[t][static_cast<std::size_t>(k)];
  return sub;
}

/// A contact pair on sub vertices: the vertex and the three face corners, each a sub-mesh vertex
/// (sub >= 0) or, when outside the active region, a constant position.
struct SubPair {
  std::array<int, 4> sub{};              // −1: constant
  std::array<double, 4> sign{};          // 1, −w0, −w1, −w2
  std::array<Eigen::Vector3d, 4> fixed;  // positions of constant participants
  Eigen::Vector3d normal;
  double gap;
  double stiffness;

  double gap_at(const Eigen::VectorXd& y) const {
    Eigen::Vector3d d = Eigen::Vector3d::Zero();
    for (std::size_t k = 0; k < 4; ++k)
      d += sign[k] * (sub[k] >= 0 ? Eigen::Vector3d(y.segment<3>(3 * sub[k])) : fixed[k]);
    return normal.dot(d) - gap;
  }
};

std::vector<SubPair> contact_sub_pairs(const std::map<std::pair<int, int>, ContactPair>& pairs,
                                       const std::vector<std::vector<int>>& local,
                                       const TetMesh* const meshes[2]) {
  std::vector<SubPair> sub_pairs;
  for (const auto& [key, pair] : pairs) {
    SubPair sp{};
    const int other = 1 - pair.mesh;
    const int corners[4] = {pair.vertex, pair.face[0], pair.face[1], pair.face[2]};
    const int owner[4] = {pair.mesh, other, other, other};
    for (int k = 0; k < 4; ++k) {
      const auto ks = static_cast<std::size_t>(k);
      sp.sub[ks] = local[static_cast<std::size_t>(owner[k])][static_cast<std::size_t>(corners[k])];
      sp.sign[ks] = k == 0 ? 1.0 : -pair.weights[k - 1];
      sp.fixed[ks] = meshes[owner[k]]->vertices.row(corners[k]).transpose();
    }
    sp.normal = pair.normal;
    sp.gap = pair.gap;
    sp.stiffness = pair.stiffness;
    sub_pairs.push_back(sp);
  }
  return sub_pairs;
}

/// The energy of a contact round on the sub-mesh: elasticity (identity plastic strains), the
/// anchors of the free vertices to their input positions, and the one-sided contact penalties.
struct ContactRoundEnergy {
  const ContactSubMesh& sub;
  const std::vector<SubPair>& sub_pairs;
  PlasticElasticEnergy& energy;
  Eigen::VectorXd s;
  double anchor = 0.0;
  Eigen::VectorXd x_input;

  // The contact Hessians c JᵀJ (upper triangle), J = [n, −w0 n, −w1 n, −w2 n]ᵀ. Inactive pairs
  // keep explicit zero entries, so the pattern is the same for the whole round.
  Eigen::SparseMatrix<double> contact_hessian(const Eigen::VectorXd& y) const {
    const auto n = static_cast<Eigen::Index>(sub.global.size());
    std::vector<Eigen::Triplet<double>> triplets;
    for (const SubPair& sp : sub_pairs) {
      const double g = sp.gap_at(y);
      const double c = g < 0.0 ? sp.stiffness : 0.0;
      const Eigen::Matrix3d nn = sp.normal * sp.normal.transpose();
      for (std::size_t p = 0; p < 4; ++p) {
        for (std::size_t q = 0; q < 4; ++q) {
          if (sp.sub[p] < 0 || sp.sub[q] < 0 || sp.sub[p] > sp.sub[q]) continue;
          const Eigen::Matrix3d block = c * sp.sign[p] * sp.sign[q] * nn;
          for (int r = 0; r < 3; ++r)
            for (int col = 0; col < 3; ++col)
              if (sp.sub[p] < sp.sub[q] || r <= col)
                triplets.emplace_back(3 * sp.sub[p] + r, 3 * sp.sub[q] + col, block(r, col));
        }
      }
    }
    Eigen::SparseMatrix<double> P(3 * n, 3 * n);
    P.setFromTriplets(triplets.begin(), triplets.end());
    return P;
  }

  bool inverted(const Eigen::VectorXd& y) const {
    const common::TetIndices& tets = sub.tets;
    for (Eigen::Index t = 0; t < tets.rows(); ++t) {
      common::Matrix3x4d X;
      for (int k = 0; k < 4; ++k) X.col(k) = y.segment<3>(3 * tets(t, k));
      if (!(common::signed_volume(X) > 0.0)) return true;
    }
    return false;
  }

  // Total energy and (optionally) gradient with the fixed dofs' entries zeroed.
  std::optional<double> total(const Eigen::VectorXd& y, Eigen::VectorXd* gradient,
                              bool stiffness) const {
    const auto n = static_cast<Eigen::Index>(sub.global.size());
    const std::vector<char>& is_free = sub.is_free;
    PlasticEnergyRequest request;
    request.gradient_x = gradient != nullptr;
    request.stiffness = stiffness;
    if (!energy.evaluate(s, y, request).valid()) return std::nullopt;
    double e = energy.energy();
    if (gradient != nullptr) *gradient = energy.gradient_x();
    for (Eigen::Index i = 0; i < n; ++i) {
      if (is_free[static_cast<std::size_t>(i)] == 0) continue;
      const Eigen::Vector3d d = y.segment<3>(3 * i) - x_input.segment<3>(3 * i);
      e += 0.5 * anchor * d.squaredNorm();
      if (gradient != nullptr) gradient->segment<3>(3 * i) += anchor * d;
    }
    for (const SubPair& sp : sub_pairs) {
      const double g = sp.gap_at(y);
      if (g >= 0.0) continue;
      e += 0.5 * sp.stiffness * g * g;
      if (gradient == nullptr) continue;
      for (std::size_t k = 0; k < 4; ++k)
        if (sp.sub[k] >= 0)
          gradient->segment<3>(3 * sp.sub[k]) += sp.stiffness * g * sp.sign[k] * sp.normal;
    }
    if (gradient != nullptr) {
      for (Eigen::Index i = 0; i < n; ++i)
        if (is_free[static_cast<std::size_t>(i)] == 0) gradient->segment<3>(3 * i).setZero();
      if (!gradient->allFinite()) return std::nullopt;
    }
    if (!std::isfinite(e)) return std::nullopt;
    return e;
  }
};

/// The contact solve on the active regions of both meshes: Newton with CHOLMOD on the free dofs.
/// rest_a/rest_b are the input shapes (the rest shapes of the elastic energy); a/b hold the current
/// positions and receive the new ones (free vertices only).
RoundResult solve_round(TetMesh& a, TetMesh& b, const TetMesh& rest_a, const TetMesh& rest_b,
                        const Region& region_a, const Region& region_b,
                        const std::map<std::pair<int, int>, ContactPair>& pairs,
                        const common::StableNeoHookean& material, double h,
                        const InterpenetrationOptions& options) {
  RoundResult result;
  const TetMesh* const meshes[2] = {&a, &b};
  const TetMesh* const rests[2] = {&rest_a, &rest_b};
  const Region* const regions[2] = {&region_a, &region_b};
  ContactSubMesh sub = contact_sub_mesh(meshes, rests, regions);
  const auto n = static_cast<Eigen::Index>(sub.global.size());
  const std::vector<char>& is_free = sub.is_free;
  Eigen::VectorXd& x = sub.x;

  PlasticElasticEnergyOptions energy_options;
  energy_options.projection = common::HessianProjection::kProjectElement;
  energy_options.storage = common::PatternStorage::kUpper;
  auto energy = PlasticElasticEnergy::create(sub.rest, sub.tets, material, energy_options);
  if (!energy) {
    result.failure = "the active region is not a valid tet mesh";
    return result;
  }
  const std::vector<SubPair> sub_pairs = contact_sub_pairs(pairs, sub.local, meshes);
  ContactRoundEnergy round{sub,
                           sub_pairs,
                           *energy,
                           identity_plastic_strains(sub.tets.rows()),
                           kAnchorStiffness * material.mu() * h,
                           Eigen::VectorXd(3 * n)};
  for (Eigen::Index i = 0; i < n; ++i)
    round.x_input.segment<3>(3 * i) = sub.rest.row(i).transpose();
  const double anchor = round.anchor;

  SparseCholesky cholesky;
  Eigen::VectorXd gradient(3 * n), step(3 * n), trial(3 * n);
  const double tolerance = options.force_tolerance * material.mu() * h * h;
  std::optional<double> e = round.total(x, &gradient, true);
  if (!e) {
    result.failure = "non-finite energy at the start of the round";
    return result;
  }
  for (int iteration = 0;; ++iteration) {
    if (gradient.lpNorm<Eigen::Infinity>() <= tolerance) break;
    if (iteration >= options.max_newton_iterations) break;  // the outer loop re-detects
    result.newton_iterations = iteration + 1;
    // Stiffness of the free dofs: projected K + anchor + active penalty blocks; the fixed dofs'
    // rows and columns become identity (their step is zero).
    Eigen::SparseMatrix<double> H = energy->stiffness() + round.contact_hessian(x);
    for (Eigen::Index i = 0; i < n; ++i) {
      if (is_free[static_cast<std::size_t>(i)] == 0) continue;
      for (int k = 0; k < 3; ++k) H.coeffRef(3 * i + k, 3 * i + k) += anchor;
    }

    for (Eigen::Index col = 0; col < H.outerSize(); ++col) {
      for (Eigen::SparseMatrix<double>::InnerIterator it(H, col); it; ++it) {
        const bool fixed = is_free[static_cast<std::size_t>(it.row() / 3)] == 0 ||
                           is_free[static_cast<std::size_t>(it.col() / 3)] == 0;
        if (fixed) it.valueRef() = it.row() == it.col() ? 1.0 : 0.0;
      }
    }
    if (iteration == 0 && cholesky.analyse(H) != SparseCholeskyStatus::kOk) {
      result.failure = "CHOLMOD analysis failed";
      return result;
    }
    if (const SparseCholeskyStatus f = cholesky.factorise(H); f != SparseCholeskyStatus::kOk) {
      result.failure = std::string("factorisation: ") + to_string(f);
      return result;
    }
    if (cholesky.solve(gradient, step) != SparseCholeskyStatus::kOk || !step.allFinite()) {
      result.failure = "non-finite Newton step";
      return result;
    }
    step = -step;
    const double slope = gradient.dot(step);
    if (!(slope < 0.0)) {
      result.failure = "no descent direction";
      return result;
    }
    double alpha = 1.0;
    bool accepted = false;
    std::optional<double> e_trial;
    for (int k = 0; k < 40; ++k, alpha *= 0.5) {
      trial = x + alpha * step;
      if (round.inverted(trial)) continue;
      e_trial = round.total(trial, nullptr, false);
      if (!e_trial) continue;
      const double slack = kEnergyRoundoff * (std::abs(*e) + std::abs(*e_trial));
      if (*e_trial <= *e + 1e-4 * alpha * slope + slack) {
        accepted = true;
        break;
      }
    }
    if (!accepted) {
      // At round-off level the energy cannot resolve the decrease: keep the state reached.
      if (gradient.lpNorm<Eigen::Infinity>() <= 1e3 * tolerance) break;
      result.failure = "line search found no acceptable step";
      break;
    }
    x = trial;
    e = round.total(x, &gradient, true);
    if (!e) {
      result.failure = "non-finite energy";
      return result;
    }
  }
  // Write back the free vertices (fixed ones keep their input bits).
  for (Eigen::Index i = 0; i < n; ++i) {
    if (is_free[static_cast<std::size_t>(i)] == 0) continue;
    const auto [m, v] = sub.global[static_cast<std::size_t>(i)];
    TetMesh& mesh = m == 0 ? a : b;
    mesh.vertices.row(v) = x.segment<3>(3 * i).transpose();
  }
  result.ok = result.failure.empty();
  return result;
}

std::optional<std::string> check_mesh(const TetMesh& mesh, const char* name) {
  if (mesh.tets.rows() == 0) return std::string(name) + " has no tets";
  if (mesh.tets.minCoeff() < 0 || mesh.tets.maxCoeff() >= mesh.vertices.rows())
    return std::string(name) + " has a tet with a vertex index out of range";
  if (!mesh.vertices.allFinite()) return std::string(name) + " has a non-finite vertex";
  for (Eigen::Index t = 0; t < mesh.tets.rows(); ++t) {
    common::Matrix3x4d X;
    for (int k = 0; k < 4; ++k) X.col(k) = mesh.vertices.row(mesh.tets(t, k)).transpose();
    if (!(common::signed_volume(X) > 0.0))
      return std::string(name) + " tet " + std::to_string(t) +
             " is inverted or degenerate (tets must be right-handed)";
  }
  return std::nullopt;
}

}  // namespace

std::optional<std::string> InterpenetrationOptions::validate() const {
  if (ring_size < 0) return field_error("ring_size", ring_size, ">= 0");
  if (!(contact_margin >= 0.0 && contact_margin < 1.0))
    return field_error("contact_margin", contact_margin, "in [0, 1)");
  if (!(std::isfinite(penalty_stiffness) && penalty_stiffness > 0.0))
    return field_error("penalty_stiffness", penalty_stiffness, "finite and > 0");
  if (!(std::isfinite(penalty_growth) && penalty_growth >= 1.0))
    return field_error("penalty_growth", penalty_growth, "finite and >= 1");
  if (max_iterations < 1) return field_error("max_iterations", max_iterations, ">= 1");
  if (max_newton_iterations < 1)
    return field_error("max_newton_iterations", max_newton_iterations, ">= 1");
  if (!(force_tolerance > 0.0 && force_tolerance < 1.0))
    return field_error("force_tolerance", force_tolerance, "in (0, 1)");
  if (auto error = material.validate()) return "InterpenetrationOptions::material." + *error;
  return std::nullopt;
}

const char* to_string(InterpenetrationStatus status) {
  switch (status) {
    case InterpenetrationStatus::kNoContact:
      return "no_contact";
    case InterpenetrationStatus::kSeparated:
      return "separated";
    case InterpenetrationStatus::kMaxIterations:
      return "max_iterations";
    case InterpenetrationStatus::kSolverFailed:
      return "solver_failed";
    case InterpenetrationStatus::kInvalidInput:
      return "invalid_input";
  }
  return "unknown";
}

std::string InterpenetrationSummary::brief_report() const {
  if (status == InterpenetrationStatus::kInvalidInput)
    return std::string("invalid input: ") + message;
  std::ostringstream o;
  o.precision(4);
  o << to_string(status) << ": penetrating vertices A in B " << penetrating_a_before << " -> "
    << penetrating_a_after << ", B in A " << penetrating_b_before << " -> " << penetrating_b_after
    << "; max depth " << max_depth_before << " -> " << max_depth_after << "; active tets "
    << active_tets_a << " + " << active_tets_b << "; " << vertices_moved << " vertices moved, max "
    << max_displacement << "; " << iterations << " rounds, " << newton_iterations
    << " Newton iterations, " << seconds << " s";
  return o.str();
}

std::optional<Penetrations> find_penetrations(const TetMesh& mesh, const TetMesh& other) {
  if (check_mesh(mesh, "mesh") || check_mesh(other, "other")) return std::nullopt;
  auto detector = Detector::create(mesh, other);
  if (!detector) return std::nullopt;
  const auto contacts = detector->detect(mesh, other);
  if (!contacts) return std::nullopt;
  std::vector<Contact> sorted = *contacts;
  std::sort(sorted.begin(), sorted.end(),
            [](const Contact& l, const Contact& r) { return l.vertex < r.vertex; });
  Penetrations p;
  p.vertices.resize(static_cast<Eigen::Index>(sorted.size()));
  p.depths.resize(static_cast<Eigen::Index>(sorted.size()));
  for (std::size_t i = 0; i < sorted.size(); ++i) {
    p.vertices[static_cast<Eigen::Index>(i)] = sorted[i].vertex;
    p.depths[static_cast<Eigen::Index>(i)] = sorted[i].depth;
  }
  return p;
}

InterpenetrationSummary remove_interpenetration(TetMesh& a, TetMesh& b,
                                                const InterpenetrationOptions& options) {
  const Clock::time_point start = Clock::now();
  InterpenetrationSummary summary;
  const auto invalid = [&](const std::string& message) {
    summary.status = InterpenetrationStatus::kInvalidInput;
    summary.message = message;
    summary.seconds = seconds_since(start);
    return summary;
  };
  if (auto error = options.validate()) return invalid(*error);
  if (auto error = check_mesh(a, "mesh A")) return invalid(*error);
  if (auto error = check_mesh(b, "mesh B")) return invalid(*error);
  const auto material = common::StableNeoHookean::create(options.material);
  if (!material) return invalid("invalid material");
  auto detect_a = Detector::create(a, b);
  auto detect_b = Detector::create(b, a);
  if (!detect_a || !detect_b) return invalid("a mesh has a non-manifold or invalid boundary");
  {
    double sum = 0.0;
    Eigen::Index count = 0;
    mean_edge_length(a, &sum, &count);
    summary.mean_edge_length = mean_edge_length(b, &sum, &count);
  }
  const double h = summary.mean_edge_length;
  summary.margin = options.contact_margin * h;

  const auto detect = [&](std::vector<Contact>* in_b, std::vector<Contact>* in_a) {
    const Clock::time_point t0 = Clock::now();
    auto ca = detect_a->detect(a, b);
    auto cb = detect_b->detect(b, a);
    summary.detection_seconds += seconds_since(t0);
    if (!ca || !cb) return false;
    *in_b = std::move(*ca);
    *in_a = std::move(*cb);
    return true;
  };
  std::vector<Contact> a_in_b, b_in_a;
  if (!detect(&a_in_b, &b_in_a)) return invalid("collision detection failed (non-finite mesh?)");
  summary.penetrating_a_before = static_cast<Eigen::Index>(a_in_b.size());
  summary.penetrating_b_before = static_cast<Eigen::Index>(b_in_a.size());
  summary.max_depth_before = std::max(max_depth(a_in_b), max_depth(b_in_a));
  summary.penetrating_a_after = summary.penetrating_a_before;
  summary.penetrating_b_after = summary.penetrating_b_before;
  summary.max_depth_after = summary.max_depth_before;
  if (a_in_b.empty() && b_in_a.empty()) {
    summary.status = InterpenetrationStatus::kNoContact;
    summary.message = "the meshes do not inter-penetrate";
    summary.seconds = seconds_since(start);
    return summary;
  }

  const TetMesh input_a = a, input_b = b;
  Region region_a(a), region_b(b);
  std::map<std::pair<int, int>, ContactPair> pairs;  // (mesh, vertex) -> contact
  const double base_stiffness = options.penalty_stiffness * material->mu() * h;
  summary.status = InterpenetrationStatus::kMaxIterations;
  for (int round = 0; round < options.max_iterations; ++round) {
    summary.iterations = round + 1;
    // Contact pairs for the vertices inside now (vertex against the closest face of the other
    // mesh); the vertex and the face corners seed the active regions.
    for (int m = 0; m < 2; ++m) {
      const std::vector<Contact>& contacts = m == 0 ? a_in_b : b_in_a;
      Region& region = m == 0 ? region_a : region_b;
      Region& other_region = m == 0 ? region_b : region_a;
      for (const Contact& c : contacts) {
        ContactPair pair;
        pair.mesh = m;
        pair.vertex = c.vertex;
        pair.face = c.face;
        pair.weights = c.weights;
        pair.normal = c.normal;
        pair.gap = summary.margin;
        const auto key = std::make_pair(m, c.vertex);
        const auto previous = pairs.find(key);
        pair.stiffness = previous == pairs.end()
                             ? base_stiffness
                             : previous->second.stiffness * options.penalty_growth;
        pairs[key] = pair;
        region.seed_vertices[static_cast<std::size_t>(c.vertex)] = 1;
        for (const int f : c.face) other_region.seed_vertices[static_cast<std::size_t>(f)] = 1;
      }
    }
    region_a.grow(options.ring_size);
    region_b.grow(options.ring_size);
    const RoundResult r =
        solve_round(a, b, input_a, input_b, region_a, region_b, pairs, *material, h, options);
    summary.newton_iterations += r.newton_iterations;
    if (!detect(&a_in_b, &b_in_a)) {
      summary.status = InterpenetrationStatus::kSolverFailed;
      summary.message = "collision detection failed after round " + std::to_string(round + 1);
      break;
    }
    if (!r.ok) {
      summary.status = InterpenetrationStatus::kSolverFailed;
      summary.message = "round " + std::to_string(round + 1) + ": " + r.failure;
      break;
    }
    if (a_in_b.empty() && b_in_a.empty()) {
      summary.status = InterpenetrationStatus::kSeparated;
      break;
    }
  }
  summary.penetrating_a_after = static_cast<Eigen::Index>(a_in_b.size());
  summary.penetrating_b_after = static_cast<Eigen::Index>(b_in_a.size());
  summary.max_depth_after = std::max(max_depth(a_in_b), max_depth(b_in_a));
  summary.active_tets_a = region_a.active_tets();
  summary.active_tets_b = region_b.active_tets();
  summary.free_vertices =
      static_cast<Eigen::Index>(std::count(region_a.free.begin(), region_a.free.end(), 1) +
                                std::count(region_b.free.begin(), region_b.free.end(), 1));
  for (int m = 0; m < 2; ++m) {
    const TetMesh& now = m == 0 ? a : b;
    const TetMesh& before = m == 0 ? input_a : input_b;
    for (Eigen::Index v = 0; v < now.vertices.rows(); ++v) {
      const double d = (now.vertices.row(v) - before.vertices.row(v)).norm();
      if (now.vertices.row(v) != before.vertices.row(v)) ++summary.vertices_moved;
      summary.max_displacement = std::max(summary.max_displacement, d);
    }
  }
  if (summary.status == InterpenetrationStatus::kSeparated) {
    summary.message = "separated in " + std::to_string(summary.iterations) + " round(s)";
  } else if (summary.status == InterpenetrationStatus::kMaxIterations) {
    summary.message = std::to_string(summary.penetrating_a_after + summary.penetrating_b_after) +
                      " boundary vertices still inside after " +
                      std::to_string(summary.iterations) + " rounds";
  }
  summary.seconds = seconds_since(start);
  return summary;
}

}  // namespace sinew::offline
