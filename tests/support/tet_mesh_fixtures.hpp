#pragma once
/// Small tetrahedral meshes for tests of common/fem and common/material.

#include <Eigen/Core>
#include <utility>

#include "common/fem/sparse_assembly.hpp"
#include "common/fem/tet4.hpp"

namespace sinew::testing {

struct TetMesh {
  Eigen::MatrixXd rest_positions;  ///< #V by 3, metres
  sinew::common::TetIndices tets;  ///< #T by 4, positive rest volumes
};

/// A box of nx·ny·nz cubes of side h, each cut into the 6 tets of the Kuhn (Freudenthal)
/// subdivision along its main diagonal; conforming across cubes, all tets right-handed.
inline TetMesh make_box_mesh(int nx, int ny, int nz, double h = 1.0) {
  TetMesh mesh;
  const auto vertex = [&](int i, int j, int k) { return i + (nx + 1) * (j + (ny + 1) * k); };
  mesh.rest_positions.resize((nx + 1) * (ny + 1) * (nz + 1), 3);
  for (int k = 0; k <= nz; ++k) {
    for (int j = 0; j <= ny; ++j) {
      for (int i = 0; i <= nx; ++i) mesh.rest_positions.row(vertex(i, j, k)) << h * i, h * j, h * k;
    }
  }
  // Corners c = bx + 2 by + 4 bz of a cube; the six Kuhn tets all contain corners 0 and 7.
  const int kuhn[6][4] = {{0, 1, 3, 7}, {0, 3, 2, 7}, {0, 2, 6, 7},
                          {0, 6, 4, 7}, {0, 4, 5, 7}, {0, 5, 1, 7}};
  mesh.tets.resize(6 * nx * ny * nz, 4);
  int t = 0;
  for (int k = 0; k < nz; ++k) {
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i) {
        for (const auto& tet : kuhn) {
          for (int a = 0; a < 4; ++a) {
            const int c = tet[a];
            mesh.tets(t, a) = vertex(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1));
          }
          sinew::common::Matrix3x4d X;
          for (int a = 0; a < 4; ++a)
            X.col(a) = mesh.rest_positions.row(mesh.tets(t, a)).transpose();
          if (sinew::common::signed_volume(X) < 0) std::swap(mesh.tets(t, 2), mesh.tets(t, 3));
          ++t;
        }
      }
    }
  }
  return mesh;
}

}  // namespace sinew::testing
