#include "offline/plastic/plastic_strain_laplacian.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <utility>
#include <vector>

#include "offline/plastic/plastic_strain.hpp"

namespace sinew::offline {

namespace {

struct TetFace {
  std::array<int, 3> vertices;  // sorted
  int tet;
};

// Union-find with path halving, for the connected components.
int find_root(std::vector<int>& parent, int i) {
  while (parent[static_cast<std::size_t>(i)] != i) {
    parent[static_cast<std::size_t>(i)] =
        parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(i)])];
    i = parent[static_cast<std::size_t>(i)];
  }
  return i;
}

}  // namespace

const std::array<double, 6>& plastic_strain_laplacian_weights() {
  static const std::array<double, 6> w = [] {
    std::array<double, 6> weights{};
    for (int k = 0; k < kPlasticStrainSize; ++k) {
      weights[static_cast<std::size_t>(k)] = is_off_diagonal_component(k) ? std::sqrt(2.0) : 1.0;
    }
    return weights;
  }();
  return w;
}

const char* to_string(TetAdjacencyStatus status) {
  switch (status) {
    case TetAdjacencyStatus::kOk:
      return "ok";
    case TetAdjacencyStatus::kNegativeIndex:
      return "negative vertex index";
    case TetAdjacencyStatus::kRepeatedVertex:
      return "tet with a repeated vertex";
  }
  return "unknown";
}

TetAdjacency tet_face_adjacency(const common::TetIndices& tets) {
  TetAdjacency adjacency;
  const Eigen::Index m = tets.rows();
  std::vector<TetFace> faces;
  faces.reserve(static_cast<std::size_t>(4 * m));
  for (Eigen::Index t = 0; t < m; ++t) {
    std::array<int, 4> v = {tets(t, 0), tets(t, 1), tets(t, 2), tets(t, 3)};
    std::sort(v.begin(), v.end());
    if (v[0] < 0) {
      adjacency.status = TetAdjacencyStatus::kNegativeIndex;
      adjacency.bad_tet = t;
      return adjacency;
    }
    if (v[0] == v[1] || v[1] == v[2] || v[2] == v[3]) {
      adjacency.status = TetAdjacencyStatus::kRepeatedVertex;
      adjacency.bad_tet = t;
      return adjacency;
    }
    for (int omit = 0; omit < 4; ++omit) {
      TetFace face{{}, static_cast<int>(t)};
      int c = 0;
      for (int a = 0; a < 4; ++a) {
        if (a != omit)
          face.vertices[static_cast<std::size_t>(c++)] = v[static_cast<std::size_t>(a)];
      }
      faces.push_back(face);
    }
  }
  std::sort(faces.begin(), faces.end(), [](const TetFace& a, const TetFace& b) {
    return a.vertices != b.vertices ? a.vertices < b.vertices : a.tet < b.tet;
  });

  std::vector<std::pair<int, int>> pairs;
  for (std::size_t begin = 0; begin < faces.size();) {
    std::size_t end = begin + 1;
    while (end < faces.size() && faces[end].vertices == faces[begin].vertices) ++end;
    if (end - begin > 2) ++adjacency.non_manifold_faces;
    for (std::size_t i = begin; i < end; ++i) {
      for (std::size_t j = i + 1; j < end; ++j) {
        if (faces[i].tet != faces[j].tet) pairs.emplace_back(faces[i].tet, faces[j].tet);
      }
    }
    begin = end;
  }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());

  adjacency.pairs.resize(static_cast<Eigen::Index>(pairs.size()), 2);
  std::vector<int> parent(static_cast<std::size_t>(m));
  std::iota(parent.begin(), parent.end(), 0);
  for (std::size_t p = 0; p < pairs.size(); ++p) {
    const auto [i, j] = pairs[p];
    adjacency.pairs(static_cast<Eigen::Index>(p), 0) = i;
    adjacency.pairs(static_cast<Eigen::Index>(p), 1) = j;
    const int ri = find_root(parent, i);
    const int rj = find_root(parent, j);
    if (ri != rj) parent[static_cast<std::size_t>(std::max(ri, rj))] = std::min(ri, rj);
  }
  for (Eigen::Index t = 0; t < m; ++t) {
    if (find_root(parent, static_cast<int>(t)) == static_cast<int>(t)) ++adjacency.num_components;
  }
  return adjacency;
}

Eigen::SparseMatrix<double> scalar_tet_laplacian(const TetAdjacency& adjacency,
                                                 Eigen::Index num_tets) {
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(static_cast<std::size_t>(num_tets + 4 * adjacency.pairs.rows()));
  for (Eigen::Index p = 0; p < adjacency.pairs.rows(); ++p) {
    const int i = adjacency.pairs(p, 0);
    const int j = adjacency.pairs(p, 1);
    entries.emplace_back(i, j, -1.0);
    entries.emplace_back(j, i, -1.0);
    entries.emplace_back(i, i, 1.0);  // duplicates are summed: the diagonal is the degree
    entries.emplace_back(j, j, 1.0);
  }
  Eigen::SparseMatrix<double> L(num_tets, num_tets);
  L.setFromTriplets(entries.begin(), entries.end());
  L.makeCompressed();
  return L;
}

Eigen::SparseMatrix<double> plastic_strain_laplacian(const TetAdjacency& adjacency,
                                                     Eigen::Index num_tets) {
  const Eigen::SparseMatrix<double> L_sc = scalar_tet_laplacian(adjacency, num_tets);
  const std::array<double, 6>& w = plastic_strain_laplacian_weights();
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(static_cast<std::size_t>(kPlasticStrainSize * L_sc.nonZeros()));
  for (Eigen::Index j = 0; j < L_sc.outerSize(); ++j) {
    for (Eigen::SparseMatrix<double>::InnerIterator it(L_sc, j); it; ++it) {
      for (int k = 0; k < kPlasticStrainSize; ++k) {
        entries.emplace_back(kPlasticStrainSize * it.row() + k, kPlasticStrainSize * it.col() + k,
                             w[static_cast<std::size_t>(k)] * it.value());
      }
    }
  }
  const Eigen::Index n = kPlasticStrainSize * num_tets;
  Eigen::SparseMatrix<double> L(n, n);
  L.setFromTriplets(entries.begin(), entries.end());
  L.makeCompressed();
  return L;
}

PlasticStrainLaplacian make_plastic_strain_laplacian(const common::TetIndices& tets) {
  PlasticStrainLaplacian result;
  result.adjacency = tet_face_adjacency(tets);
  if (!result.ok()) return result;
  result.scalar = scalar_tet_laplacian(result.adjacency, tets.rows());
  result.matrix = plastic_strain_laplacian(result.adjacency, tets.rows());
  return result;
}

Eigen::MatrixXd plastic_strain_laplacian_nullspace(Eigen::Index num_tets) {
  Eigen::MatrixXd psi = Eigen::MatrixXd::Zero(kPlasticStrainSize * num_tets, kPlasticStrainSize);
  if (num_tets == 0) return psi;
  const double value = 1.0 / std::sqrt(static_cast<double>(num_tets));
  for (Eigen::Index t = 0; t < num_tets; ++t) {
    for (int k = 0; k < kPlasticStrainSize; ++k) psi(kPlasticStrainSize * t + k, k) = value;
  }
  return psi;
}

}  // namespace sinew::offline
