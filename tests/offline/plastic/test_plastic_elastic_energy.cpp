// Tests of offline/plastic_elastic_energy: the per-tet energy E = det(Fp)·V₀·ψ(F·Fp⁻¹) of seed 003
// (eq. 1) with its derivatives in x, in s and mixed (appendix B) against finite differences at
// seeded points (including an Fp eigenvalue near the 0.01 floor and a nearly flat tet); the
// whole-mesh assembly of f_e, K, ∂f_e/∂s and ∂E/∂s on a box mesh; the cross-check with
// common::TetMeshElasticity at Fp = I; the equilibrium x = c·X under uniform Fp = c·I; and the
// absence of allocations in evaluate().

#include "offline/plastic/plastic_elastic_energy.hpp"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "common/fem/tet_mesh_elasticity.hpp"
// The one translation unit of this executable that includes it: malloc and operator new hooks.
#include "tests/support/allocation_counter.hpp"
#include "tests/support/finite_difference.hpp"
#include "tests/support/tet_mesh_fixtures.hpp"

namespace {

using sinew::common::Matrix12d;
using sinew::common::Matrix3x4d;
using sinew::common::StableNeoHookean;
using sinew::common::Vector12d;
using sinew::offline::Matrix12x6d;
using sinew::offline::Matrix6d;
using sinew::offline::PlasticElasticEnergy;
using sinew::offline::PlasticEnergyRequest;
using sinew::offline::PlasticEvaluationStatus;
using sinew::offline::PlasticStrainStatus;
using sinew::offline::PlasticTetOutputs;
using sinew::offline::Vector6d;
using sinew::testing::derivatives_match;

StableNeoHookean tissue() {
  return *StableNeoHookean::create({/*youngs_modulus=*/3e3, /*poisson_ratio=*/0.45});
}

Vector6d symmetric_with_eigenvalues(const Eigen::Vector3d& eigenvalues, std::mt19937& gen) {
  const Eigen::Matrix3d Q = sinew::testing::random_rotation(gen);
  return sinew::offline::plastic_strain_vector(Q * eigenvalues.asDiagonal() * Q.transpose());
}

// ---------------------------------------------------------------------------------------------
// One tet.

struct TetCase {
  std::string name;
  Matrix3x4d rest;       // X0..X3
  Vector6d s;            // plastic strain
  Matrix3x4d positions;  // x0..x3
  double h_x;            // finite-difference steps
  double h_s;
};

Matrix3x4d regular_tet() {
  Matrix3x4d X;
  X << 0.0, 1.0, 0.0, 0.0,  //
      0.0, 0.0, 1.0, 0.0,   //
      0.0, 0.0, 0.0, 1.0;
  return X;
}

std::vector<TetCase> tet_cases() {
  auto& gen = sinew::testing::rng();
  std::vector<TetCase> cases;
  const auto deform = [&](const Matrix3x4d& X, const Eigen::Matrix3d& A, double noise) {
    Matrix3x4d x = A * X;
    x.colwise() += sinew::testing::random_vector(3, 0.5, gen);
    return Matrix3x4d(x + noise * Eigen::Map<const Matrix3x4d>(
                                      sinew::testing::random_vector(12, 1.0, gen).data()));
  };
  const Eigen::Matrix3d R = sinew::testing::random_rotation(gen);
  Matrix3x4d X = regular_tet();
  X.col(1) << 0.9, 0.1, -0.05;

  cases.push_back(
      {"near identity", X,
       sinew::offline::identity_plastic_strain() + sinew::testing::random_vector(6, 0.15, gen),
       deform(X, R, 0.1), 1e-5, 1e-5});
  const Vector6d aniso = symmetric_with_eigenvalues({0.6, 1.3, 2.1}, gen);
  cases.push_back({"anisotropic Fp, large deformation", X, aniso,
                   deform(X, R * sinew::offline::plastic_strain_matrix(aniso), 0.3), 1e-5, 1e-5});
  cases.push_back({"Fp eigenvalue 0.011 near the floor", X,
                   symmetric_with_eigenvalues({0.011, 1.0, 1.5}, gen), deform(X, R, 0.05), 1e-6,
                   1e-7});
  Matrix3x4d flat = regular_tet();
  flat.col(3) << 0.3, 0.3, 2e-3;  // quality ~1e-3
  cases.push_back(
      {"nearly flat rest tet", flat,
       sinew::offline::identity_plastic_strain() + sinew::testing::random_vector(6, 0.1, gen),
       deform(flat, R, 1e-3), 1e-7, 1e-5});
  cases.push_back({"indefinite Fp (still consistent)", X,
                   symmetric_with_eigenvalues({-0.6, 0.9, 1.3}, gen), deform(X, R, 0.1), 1e-5,
                   1e-5});
  return cases;
}

// Element quantities as functions of the flattened x (12) or s (6), for the finite differences.
struct TetFunctions {
  StableNeoHookean material;
  sinew::common::Tet4Rest rest;
  Vector6d s;
  Matrix3x4d positions;

  double energy(const Vector6d& s_, const Matrix3x4d& x_) const {
    double e = 0.0;
    PlasticTetOutputs out;
    out.energy = &e;
    sinew::offline::evaluate_plastic_tet(material, rest, s_, x_, out);
    return e;
  }
  Vector12d gradient_x(const Vector6d& s_, const Matrix3x4d& x_) const {
    Vector12d g;
    PlasticTetOutputs out;
    out.gradient_x = &g;
    sinew::offline::evaluate_plastic_tet(material, rest, s_, x_, out);
    return g;
  }
  Vector6d gradient_s(const Vector6d& s_, const Matrix3x4d& x_) const {
    Vector6d g;
    PlasticTetOutputs out;
    out.gradient_s = &g;
    sinew::offline::evaluate_plastic_tet(material, rest, s_, x_, out);
    return g;
  }
};

Matrix3x4d to_positions(const Eigen::VectorXd& x) {
  return Eigen::Map<const Matrix3x4d>(x.data());
}

TEST(PlasticTet, DerivativesMatchFiniteDifferences) {
  const StableNeoHookean material = tissue();
  for (const TetCase& c : tet_cases()) {
    SCOPED_TRACE(c.name);
    const auto rest = sinew::common::make_tet4_rest(c.rest);
    ASSERT_TRUE(rest.valid());
    const TetFunctions f{material, rest, c.s, c.positions};
    const Eigen::VectorXd x0 = sinew::common::to_element_dofs(c.positions);
    const Eigen::VectorXd s0 = c.s;

    double energy = 0.0;
    Vector12d gx;
    Vector6d gs;
    Matrix12d hxx;
    Matrix12x6d hxs;
    Matrix6d hss;
    const PlasticStrainStatus status = sinew::offline::evaluate_plastic_tet(
        material, rest, c.s, c.positions, {&energy, &gx, &gs, &hxx, &hxs, &hss});
    ASSERT_TRUE(sinew::offline::is_invertible(status));
    EXPECT_DOUBLE_EQ(energy, f.energy(c.s, c.positions));

    const auto e_of_x = [&](const Eigen::VectorXd& x) { return f.energy(c.s, to_positions(x)); };
    const auto e_of_s = [&](const Eigen::VectorXd& s) { return f.energy(s, c.positions); };
    const auto gx_of_x = [&](const Eigen::VectorXd& x) -> Eigen::VectorXd {
      return f.gradient_x(c.s, to_positions(x));
    };
    const auto gx_of_s = [&](const Eigen::VectorXd& s) -> Eigen::VectorXd {
      return f.gradient_x(s, c.positions);
    };
    const auto gs_of_s = [&](const Eigen::VectorXd& s) -> Eigen::VectorXd {
      return f.gradient_s(s, c.positions);
    };
    const auto gs_of_x = [&](const Eigen::VectorXd& x) -> Eigen::VectorXd {
      return f.gradient_s(c.s, to_positions(x));
    };
    using sinew::testing::fd_gradient;
    using sinew::testing::fd_jacobian;
    EXPECT_TRUE(derivatives_match(gx, fd_gradient(e_of_x, x0, c.h_x), 1e-6)) << "dE/dx";
    EXPECT_TRUE(derivatives_match(hxx, fd_jacobian(gx_of_x, x0, c.h_x), 1e-6)) << "d2E/dx2";
    EXPECT_TRUE(derivatives_match(gs, fd_gradient(e_of_s, s0, c.h_s), 1e-6)) << "dE/ds";
    EXPECT_TRUE(derivatives_match(hss, fd_jacobian(gs_of_s, s0, c.h_s), 1e-6)) << "d2E/ds2";
    // Mixed: the s-derivative of the analytic x-gradient, and the x-derivative of the s-gradient.
    EXPECT_TRUE(derivatives_match(hxs, fd_jacobian(gx_of_s, s0, c.h_s), 1e-6)) << "d2E/dxds";
    EXPECT_TRUE(
        derivatives_match(Eigen::MatrixXd(hxs.transpose()), fd_jacobian(gs_of_x, x0, c.h_x), 1e-6))
        << "d2E/dsdx";
    EXPECT_LT((hxx - hxx.transpose()).norm(), 1e-10 * hxx.norm());
    EXPECT_LT((hss - hss.transpose()).norm(), 1e-10 * hss.norm());
  }
}

TEST(PlasticTet, ElasticDeformationGradientJacobianMapsPositionsToFe) {
  auto& gen = sinew::testing::rng();
  const auto rest = sinew::common::make_tet4_rest(regular_tet());
  const Vector6d s = symmetric_with_eigenvalues({0.5, 1.2, 1.9}, gen);
  const Eigen::Matrix3d Fp = sinew::offline::plastic_strain_matrix(s);
  const Eigen::VectorXd x = sinew::testing::random_vector(12, 1.0, gen);
  const Eigen::Matrix3d F = sinew::common::deformation_gradient(rest, to_positions(x));
  const auto Be = sinew::offline::elastic_deformation_gradient_jacobian(rest, Fp.inverse());
  EXPECT_LT((Be * x - sinew::common::vec(F * Fp.inverse())).norm(), 1e-12 * F.norm());
}

TEST(PlasticTet, IdentityPlasticStrainIsPlainElasticity) {
  auto& gen = sinew::testing::rng();
  const StableNeoHookean material = tissue();
  const auto rest = sinew::common::make_tet4_rest(regular_tet());
  const Matrix3x4d x =
      regular_tet() +
      0.2 * Eigen::Map<const Matrix3x4d>(sinew::testing::random_vector(12, 1.0, gen).data());
  double e = 0.0;
  Vector12d g;
  Matrix12d H;
  sinew::offline::evaluate_plastic_tet(material, rest, sinew::offline::identity_plastic_strain(), x,
                                       {&e, &g, nullptr, &H, nullptr, nullptr});
  double e_ref = 0.0;
  Vector12d g_ref;
  Matrix12d H_ref;
  sinew::common::evaluate_tet_elastic(material, rest, x, &e_ref, &g_ref, &H_ref);
  ASSERT_GT(std::abs(e_ref), 1.0);
  EXPECT_NEAR(e, e_ref, 1e-12 * std::abs(e_ref));
  EXPECT_LT((g - g_ref).norm(), 1e-12 * g_ref.norm());
  EXPECT_LT((H - H_ref).norm(), 1e-12 * H_ref.norm());
}

TEST(PlasticTet, SingularPlasticStrainGivesStatusAndNaN) {
  const StableNeoHookean material = tissue();
  const auto rest = sinew::common::make_tet4_rest(regular_tet());
  Vector6d s = sinew::offline::identity_plastic_strain();
  s[5] = 0.0;  // Fp = diag(1, 1, 0)
  double e = 0.0;
  Vector12d g;
  Matrix12x6d hxs;
  const auto status = sinew::offline::evaluate_plastic_tet(material, rest, s, regular_tet(),
                                                           {&e, &g, nullptr, nullptr, &hxs});
  EXPECT_EQ(status, PlasticStrainStatus::kSingular);
  EXPECT_TRUE(std::isnan(e));
  EXPECT_TRUE(g.hasNaN());
  EXPECT_TRUE(hxs.hasNaN());
}

// ---------------------------------------------------------------------------------------------
// Whole mesh.

Eigen::VectorXd affine_map(const Eigen::VectorXd& X, const Eigen::Matrix3d& A,
                           const Eigen::Vector3d& t = Eigen::Vector3d::Zero()) {
  Eigen::VectorXd x(X.size());
  for (Eigen::Index v = 0; v < X.size() / 3; ++v) x.segment<3>(3 * v) = A * X.segment<3>(3 * v) + t;
  return x;
}

struct MeshState {
  Eigen::VectorXd s;
  Eigen::VectorXd x;
};

// Spatially varying SPD plastic strains and a deformed state near their "rest shape".
MeshState random_state(const PlasticElasticEnergy& energy, std::mt19937& gen) {
  MeshState state;
  state.s.resize(energy.num_plastic_dofs());
  for (Eigen::Index t = 0; t < energy.num_tets(); ++t) {
    const Eigen::Vector3d lambda = Eigen::Vector3d(1.0, 1.0, 1.0) +
                                   sinew::testing::random_vector(3, 0.3, gen) +
                                   Eigen::Vector3d(0.2, 0.0, -0.1);
    state.s.segment<6>(6 * t) = symmetric_with_eigenvalues(lambda, gen);
  }
  const Eigen::Matrix3d A =
      sinew::testing::random_rotation(gen) * Eigen::Vector3d(1.15, 1.0, 0.9).asDiagonal();
  state.x = affine_map(energy.rest_dofs(), A, Eigen::Vector3d(0.1, -0.2, 0.3)) +
            sinew::testing::random_vector(energy.num_dofs(), 0.04, gen);
  return state;
}

PlasticElasticEnergy make_energy(const sinew::testing::TetMesh& mesh,
                                 sinew::offline::PlasticElasticEnergyOptions options = {}) {
  auto energy = PlasticElasticEnergy::create(mesh.rest_positions, mesh.tets, tissue(), options);
  EXPECT_TRUE(energy);
  return *energy;
}

TEST(PlasticElasticEnergy, AssembledDerivativesMatchFiniteDifferences) {
  auto& gen = sinew::testing::rng();
  const auto mesh = sinew::testing::make_box_mesh(2, 1, 1, 0.5);
  PlasticElasticEnergy energy = make_energy(mesh);
  const MeshState state = random_state(energy, gen);

  const auto E = [&](const Eigen::VectorXd& s, const Eigen::VectorXd& x) {
    EXPECT_TRUE(energy.evaluate(s, x, {}).valid());
    return energy.energy();
  };
  const auto f = [&](const Eigen::VectorXd& s, const Eigen::VectorXd& x) -> Eigen::VectorXd {
    PlasticEnergyRequest request;
    request.gradient_x = true;
    EXPECT_TRUE(energy.evaluate(s, x, request).valid());
    return energy.gradient_x();
  };

  const auto result = energy.evaluate(state.s, state.x, PlasticEnergyRequest::all());
  ASSERT_EQ(result.status, PlasticEvaluationStatus::kOk) << result.message();
  const double e = energy.energy();
  const Eigen::VectorXd f_e = energy.gradient_x();
  const Eigen::VectorXd dE_ds = energy.gradient_s();
  const Eigen::MatrixXd K = energy.stiffness();
  const Eigen::MatrixXd df_ds = energy.force_jacobian();
  ASSERT_EQ(df_ds.rows(), energy.num_dofs());
  ASSERT_EQ(df_ds.cols(), energy.num_plastic_dofs());

  // The energy is the sum of the element energies.
  double sum = 0.0;
  for (Eigen::Index t = 0; t < energy.num_tets(); ++t) {
    double e_t = 0.0;
    sinew::offline::evaluate_plastic_tet(energy.material(), energy.rest()[t],
                                         state.s.segment<6>(6 * t),
                                         energy.tet_positions(t, state.x), {&e_t});
    sum += e_t;
  }
  EXPECT_NEAR(e, sum, 1e-12 * std::abs(sum));
  ASSERT_GT(std::abs(e), 1e-3);

  using sinew::testing::fd_gradient;
  using sinew::testing::fd_jacobian;
  const double h = 1e-6;
  EXPECT_TRUE(derivatives_match(
      f_e, fd_gradient([&](const Eigen::VectorXd& x) { return E(state.s, x); }, state.x, h), 1e-6))
      << "f_e";
  EXPECT_TRUE(derivatives_match(
      K, fd_jacobian([&](const Eigen::VectorXd& x) { return f(state.s, x); }, state.x, h), 1e-6))
      << "K";
  EXPECT_TRUE(derivatives_match(
      dE_ds, fd_gradient([&](const Eigen::VectorXd& s) { return E(s, state.x); }, state.s, h),
      1e-6))
      << "dE/ds";
  EXPECT_TRUE(derivatives_match(
      df_ds, fd_jacobian([&](const Eigen::VectorXd& s) { return f(s, state.x); }, state.s, h),
      1e-6))
      << "df_e/ds";
  EXPECT_EQ(energy.force_jacobian().nonZeros(), 12 * energy.num_plastic_dofs());
}

TEST(PlasticElasticEnergy, UpperStorageAndProjectionOptions) {
  auto& gen = sinew::testing::rng();
  const auto mesh = sinew::testing::make_box_mesh(1, 1, 2, 0.5);
  PlasticElasticEnergy full = make_energy(mesh);
  sinew::offline::PlasticElasticEnergyOptions options;
  options.storage = sinew::common::PatternStorage::kUpper;
  PlasticElasticEnergy upper = make_energy(mesh, options);
  const MeshState state = random_state(full, gen);
  PlasticEnergyRequest request;
  request.stiffness = true;
  ASSERT_TRUE(full.evaluate(state.s, state.x, request).valid());
  ASSERT_TRUE(upper.evaluate(state.s, state.x, request).valid());
  const Eigen::MatrixXd K_full = full.stiffness();
  const Eigen::MatrixXd K_upper =
      Eigen::MatrixXd(upper.stiffness()).selfadjointView<Eigen::Upper>();
  EXPECT_LT((K_full - K_upper).norm(), 1e-12 * K_full.norm());

  options = {};
  options.projection = sinew::common::HessianProjection::kProjectElement;
  PlasticElasticEnergy projected = make_energy(mesh, options);
  ASSERT_TRUE(projected.evaluate(state.s, state.x, request).valid());
  const Eigen::MatrixXd K_psd = projected.stiffness();
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(K_psd).eigenvalues().minCoeff(),
            -1e-9 * K_psd.norm());

  options = {};
  options.degeneracy_tolerance = -1.0;
  sinew::common::TetMeshCheck check;
  EXPECT_FALSE(
      PlasticElasticEnergy::create(mesh.rest_positions, mesh.tets, tissue(), options, &check));
  EXPECT_EQ(check.status, sinew::common::TetMeshStatus::kInvalidOptions);
  EXPECT_TRUE(options.validate()->find("degeneracy_tolerance") != std::string::npos);
}

TEST(PlasticElasticEnergy, IdentityPlasticStrainMatchesTetMeshElasticity) {
  auto& gen = sinew::testing::rng();
  const auto mesh = sinew::testing::make_box_mesh(2, 2, 1, 0.3);
  PlasticElasticEnergy energy = make_energy(mesh);
  auto elasticity =
      sinew::common::TetMeshElasticity::create(mesh.rest_positions, mesh.tets, tissue());
  ASSERT_TRUE(elasticity);
  const Eigen::VectorXd x =
      affine_map(energy.rest_dofs(), Eigen::Vector3d(1.2, 0.95, 0.8).asDiagonal()) +
      sinew::testing::random_vector(energy.num_dofs(), 0.03, gen);
  const Eigen::VectorXd s = sinew::offline::identity_plastic_strains(energy.num_tets());
  ASSERT_EQ(energy.evaluate(s, x, PlasticEnergyRequest::all()).status,
            PlasticEvaluationStatus::kOk);

  const double e_ref = elasticity->energy(x);
  Eigen::VectorXd g_ref(x.size());
  elasticity->gradient(x, g_ref);
  const Eigen::MatrixXd K_ref = elasticity->hessian(x);
  ASSERT_GT(e_ref, 1e-2);
  EXPECT_NEAR(energy.energy(), e_ref, 1e-12 * e_ref);
  EXPECT_LT((energy.gradient_x() - g_ref).norm(), 1e-12 * g_ref.norm());
  EXPECT_LT((Eigen::MatrixXd(energy.stiffness()) - K_ref).norm(), 1e-12 * K_ref.norm());
}

TEST(PlasticElasticEnergy, UniformPlasticStrainMakesItsRestShapeAnEquilibrium) {
  auto& gen = sinew::testing::rng();
  const auto mesh = sinew::testing::make_box_mesh(2, 1, 2, 0.4);
  PlasticElasticEnergy energy = make_energy(mesh);
  const Eigen::VectorXd& X = energy.rest_dofs();
  PlasticEnergyRequest request;
  request.gradient_x = true;
  request.stiffness = true;

  for (const double c : {1.7, 0.6}) {
    SCOPED_TRACE("Fp = " + std::to_string(c) + " I");
    const Eigen::VectorXd s = c * sinew::offline::identity_plastic_strains(energy.num_tets());
    // The template itself is far from equilibrium under Fp = c·I: the force scale.
    ASSERT_TRUE(energy.evaluate(s, X, request).valid());
    const double force_scale = energy.gradient_x().norm();
    const double energy_scale = energy.energy();
    ASSERT_GT(force_scale, 1.0);
    ASSERT_GT(energy_scale, 1.0);
    // x = c·X (moved rigidly too) has Fe = R: zero energy and zero force at every vertex.
    const Eigen::Matrix3d R = sinew::testing::random_rotation(gen);
    const Eigen::VectorXd x = affine_map(X, c * R, Eigen::Vector3d(0.3, -1.0, 2.0));
    ASSERT_EQ(energy.evaluate(s, x, request).status, PlasticEvaluationStatus::kOk);
    EXPECT_NEAR(energy.energy(), 0.0, 1e-10 * energy_scale);
    EXPECT_LT(energy.gradient_x().norm(), 1e-10 * force_scale);
    // Nullspace lemma (seed 003, §3.6): at an equilibrium K annihilates translations and
    // infinitesimal rotations ψ_{3+i} = (e_i × x_v)_v.
    const Eigen::MatrixXd K = energy.stiffness();
    for (int i = 0; i < 3; ++i) {
      Eigen::VectorXd translation = Eigen::VectorXd::Zero(x.size());
      Eigen::VectorXd rotation(x.size());
      for (Eigen::Index v = 0; v < x.size() / 3; ++v) {
        translation[3 * v + i] = 1.0;
        rotation.segment<3>(3 * v) =
            Eigen::Vector3d::Unit(i).cross(Eigen::Vector3d(x.segment<3>(3 * v)));
      }
      EXPECT_LT((K * translation).norm(), 1e-10 * K.norm() * translation.norm());
      EXPECT_LT((K * rotation).norm(), 1e-10 * K.norm() * rotation.norm());
    }
  }

  // The same for a uniform anisotropic Fp = A (symmetric positive definite): x = R·A·X.
  const Vector6d a = symmetric_with_eigenvalues({0.7, 1.1, 1.8}, gen);
  Eigen::VectorXd s(energy.num_plastic_dofs());
  for (Eigen::Index t = 0; t < energy.num_tets(); ++t) s.segment<6>(6 * t) = a;
  const Eigen::Matrix3d R = sinew::testing::random_rotation(gen);
  ASSERT_TRUE(energy.evaluate(s, X, request).valid());
  const double force_scale = energy.gradient_x().norm();
  ASSERT_TRUE(
      energy.evaluate(s, affine_map(X, R * sinew::offline::plastic_strain_matrix(a)), request)
          .valid());
  EXPECT_LT(energy.gradient_x().norm(), 1e-10 * force_scale);
}

TEST(PlasticElasticEnergy, FailuresAreStatuses) {
  auto& gen = sinew::testing::rng();
  const auto mesh = sinew::testing::make_box_mesh(1, 1, 1);
  PlasticElasticEnergy energy = make_energy(mesh);
  MeshState state = random_state(energy, gen);
  const auto all = PlasticEnergyRequest::all();

  EXPECT_EQ(energy.evaluate(state.s.head(6), state.x, all).status,
            PlasticEvaluationStatus::kInvalidSize);
  EXPECT_EQ(energy.evaluate(state.s, state.x.head(3), all).status,
            PlasticEvaluationStatus::kInvalidSize);

  Eigen::VectorXd s = state.s;
  s.segment<6>(6 * 4) = symmetric_with_eigenvalues({-0.3, 1.0, 1.2}, gen);
  auto result = energy.evaluate(s, state.x, all);
  EXPECT_EQ(result.status, PlasticEvaluationStatus::kNotPositiveDefinite);
  ASSERT_TRUE(result.tet);
  EXPECT_EQ(*result.tet, 4);
  EXPECT_TRUE(result.valid());
  EXPECT_TRUE(energy.gradient_x().allFinite());

  s.segment<6>(6 * 2).setZero();
  result = energy.evaluate(s, state.x, all);
  EXPECT_EQ(result.status, PlasticEvaluationStatus::kSingularPlasticStrain);
  ASSERT_TRUE(result.tet);
  EXPECT_EQ(*result.tet, 2);
  EXPECT_FALSE(result.valid());
  EXPECT_NE(result.message().find("tet 2"), std::string::npos);

  Eigen::VectorXd x = state.x;
  x[5] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(energy.evaluate(state.s, x, all).status, PlasticEvaluationStatus::kNonFinite);
}

TEST(PlasticElasticEnergy, EvaluateDoesNotAllocate) {
  if (!sinew::testing::allocation_counting_available())
    GTEST_SKIP() << sinew::testing::kAllocationCountingUnavailable;
  auto& gen = sinew::testing::rng();
  const auto mesh = sinew::testing::make_box_mesh(2, 2, 2, 0.25);
  sinew::offline::PlasticElasticEnergyOptions options;
  options.projection = sinew::common::HessianProjection::kProjectDPdF;
  PlasticElasticEnergy energy = make_energy(mesh, options);
  const MeshState state = random_state(energy, gen);
  Eigen::VectorXd singular = state.s;
  singular.segment<6>(6 * 7).setZero();
  const auto all = PlasticEnergyRequest::all();
  ASSERT_TRUE(energy.evaluate(state.s, state.x, all).valid());  // warm-up

  const double* K_values = energy.stiffness().valuePtr();
  const double* J_values = energy.force_jacobian().valuePtr();
  long failures = 0;
  sinew::testing::AllocationCounter counter;
  for (int i = 0; i < 20; ++i) {
    if (!energy.evaluate(state.s, state.x, all).valid()) ++failures;
    if (energy.evaluate(singular, state.x, all).valid()) ++failures;  // failure path
  }
  counter.stop();
  EXPECT_EQ(counter.total(), 0);
  EXPECT_EQ(failures, 0);
  EXPECT_EQ(energy.stiffness().valuePtr(), K_values);
  EXPECT_EQ(energy.force_jacobian().valuePtr(), J_values);
}

}  // namespace
