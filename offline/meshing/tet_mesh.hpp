#pragma once
/// A tet mesh: the template the registration deforms (made by meshing/tet_mesher.hpp from a
/// surface, or read by io/tet_mesh_io.hpp) and its result.

#include <Eigen/Core>

namespace sinew::offline {

struct TetMesh {
  Eigen::Matrix<double, Eigen::Dynamic, 3> vertices;  ///< #V by 3
  Eigen::Matrix<int, Eigen::Dynamic, 4> tets;         ///< #T by 4, 0-based vertex indices
};

}  // namespace sinew::offline
