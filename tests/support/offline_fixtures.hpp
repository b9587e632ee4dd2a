#pragma once
/// Shared pieces of the offline/ tests: a soft-tissue material and material points at vertices.

#include <gtest/gtest.h>

#include <Eigen/Core>

#include "common/fem/sparse_assembly.hpp"
#include "common/material/stable_neo_hookean.hpp"
#include "offline/constraints.hpp"

namespace sinew::testing {

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

}  // namespace sinew::testing
