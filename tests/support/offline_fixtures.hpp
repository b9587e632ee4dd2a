#pragma once
/// Shared pieces of the offline/ tests: box meshes in the offline tools' format, a soft-tissue
/// material, material points at vertices, and a free block with a non-uniform plastic field.

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <optional>

#include "common/fem/sparse_assembly.hpp"
#include "common/material/stable_neo_hookean.hpp"
#include "offline/constraints/constraints.hpp"
#include "offline/io/tet_mesh_io.hpp"
#include "offline/plastic/plastic_elastic_energy.hpp"
#include "offline/plastic/plastic_strain.hpp"
#include "tests/support/tet_mesh_fixtures.hpp"

namespace sinew::testing {

/// make_box_mesh as the offline tools' TetMesh, its corner (0, 0, 0) moved to origin.
inline offline::TetMesh offline_box_mesh(int nx, int ny, int nz, double h,
                                         const Eigen::Vector3d& origin) {
  const TetMesh fixture = make_box_mesh(nx, ny, nz, h);
  offline::TetMesh mesh;
  mesh.vertices = fixture.rest_positions;
  mesh.vertices.rowwise() += origin.transpose();
  mesh.tets = fixture.tets;
  return mesh;
}

/// E = 10 kPa, ν = 0.4: the order of magnitude of muscle and liver tissue.
inline common::StableNeoHookean soft_tissue() {
  common::StableNeoHookeanParameters p;
  p.youngs_modulus = 1e4;
  p.poisson_ratio = 0.4;
  return *common::StableNeoHookean::create(p);
}

/// An embedded point at vertex v: the first tet that has v, weight 1 on it.
inline offline::EmbeddedPoint at_vertex(const common::TetIndices& tets, int v) {
  for (Eigen::Index t = 0; t < tets.rows(); ++t) {
    for (int a = 0; a < 4; ++a) {
      if (tets(t, a) == v) {
        offline::EmbeddedPoint p;
        p.tet = t;
        p.weights = Eigen::Vector4d::Zero();
        p.weights[a] = 1.0;
        return p;
      }
    }
  }
  ADD_FAILURE() << "vertex " << v << " is in no tet";
  return {};
}

// A 3x2x2 box of 5 cm cubes with a smooth, anisotropic plastic field (no attachments).
struct FreeBlock {
  TetMesh mesh = make_box_mesh(3, 2, 2, 0.05);
  std::optional<offline::PlasticElasticEnergy> energy =
      offline::PlasticElasticEnergy::create(mesh.rest_positions, mesh.tets, soft_tissue());
  Eigen::VectorXd s;
  FreeBlock() {
    const Eigen::Index m = mesh.tets.rows();
    s.resize(6 * m);
    for (Eigen::Index t = 0; t < m; ++t) {
      Eigen::Vector3d c = Eigen::Vector3d::Zero();
      for (int a = 0; a < 4; ++a) c += mesh.rest_positions.row(mesh.tets(t, a)).transpose() / 4;
      Eigen::Matrix3d Fp = Eigen::Matrix3d::Identity();
      Fp(0, 0) += 2.0 * c.x();                   // stretch growing along x
      Fp(1, 1) += 0.3 * std::sin(20.0 * c.x());  // a transverse wave
      Fp(0, 2) = Fp(2, 0) = 1.5 * c.y();         // shear
      s.segment<6>(6 * t) = offline::plastic_strain_vector(Fp);
    }
  }
};

}  // namespace sinew::testing
