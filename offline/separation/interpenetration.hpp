#pragma once
/// Removal of the inter-penetrations between two registered neighbouring organs (seed 003,
/// §4.1.4). Each organ is registered on its own, so two muscles in continuous contact overlap
/// where their shared boundary had little image contrast. The overlap is removed by a static FEM
/// contact solve restricted to a small region around the collision, "without displacing the rest
/// of the muscle":
///  1. collision detection: the boundary vertices of each mesh inside the other mesh's volume
///     (point-in-tet test), with their depth (distance to the other's boundary surface);
///  2. active region on each mesh: the tets touching a penetrating vertex (or a corner of the face
///     of this mesh that a vertex of the other is paired with, step 3), grown by ring_size rings of
///     face-adjacent tets, accumulated over the rounds; only vertices all of whose tets are active
///     may move, every other vertex keeps its input position exactly;
///  3. contact solve on both active regions together: minimise
///       E_a(x_a) + E_b(x_b) + Σ_k ½ c_k min(0, n_kᵀ(x_k − Σ_i w_ki x_{f_ki}) − margin)²,
///     where each organ's registered shape is its own rest shape (it is an equilibrium), and each
///     penetrating vertex k is paired with the closest point of the other surface (barycentric
///     w_ki on the face f_k, frozen for the round) along n_k, the direction from the vertex to that
///     point: a one-sided vertex-face penalty that moves BOTH surfaces, each in proportion to its
///     compliance (half the depth each for equal organs). A weak spring (1e-6·μh) ties every free
///     vertex to its input position, so an organ active as a whole has no rigid null space. Newton
///     with CHOLMOD on the free dofs, Armijo backtracking that rejects inverted tets;
///  4. re-detection (active-set loop) until no boundary vertex of either mesh is inside the other,
///     or max_iterations rounds. A vertex still inside after a round has its penalty stiffened.
///
/// Limitations. Contacts are vertex-in-volume tests: an edge of one surface crossing a face of the
/// other with both edge ends outside is not seen (shallow, well-resolved overlaps make this rare).
/// The way out is the closest-point direction, so an overlap deeper than the distance from a
/// penetrating vertex to a nearby side of the other organ pushes that vertex sideways (still
/// separated, with larger displacements and more rounds); the shallow overlaps of registered
/// neighbours (§4.1.4) are the intended input.
/// For contact islands of several organs, run it for the second organ against the first, the third
/// against the first two, and so on (§4.1.4), e.g. with the previous organs merged into one mesh.

#include <Eigen/Core>
#include <optional>
#include <string>

#include "common/material/stable_neo_hookean.hpp"
#include "offline/io/tet_mesh_io.hpp"

namespace sinew::offline {

struct InterpenetrationOptions {
  /// Rings of face-adjacent tets added around the tets touching the collision (§4.1.4: a 5-ring);
  /// ≥ 0. More rings spread the deformation more smoothly over more of the organ.
  int ring_size = 5;
  /// Gap left between the separated surfaces, as a fraction of the mean edge length of the two
  /// meshes; in [0, 1). A small positive gap keeps the result clear of round-off.
  double contact_margin = 0.01;
  /// Penalty stiffness c_k relative to μ·h (μ: the material's shear modulus, h: mean edge length);
  /// finite, > 0. Larger values leave less residual violation, at worse Newton conditioning.
  double penalty_stiffness = 1e3;
  /// Factor applied to c_k of a vertex still inside after a round; ≥ 1.
  double penalty_growth = 10.0;
  /// Rounds of detection + contact solve; ≥ 1.
  int max_iterations = 20;
  /// Newton iterations per round; ≥ 1.
  int max_newton_iterations = 50;
  /// Newton convergence: ‖∇Π‖∞ on the free dofs ≤ force_tolerance·μh²; in (0, 1).
  double force_tolerance = 1e-8;
  /// Soft tissue. Only the ratio of the penalty to μ and Poisson's ratio matter (there is no other
  /// load), so the result does not depend on the units of E.
  common::StableNeoHookeanParameters material{};

  /// Empty when valid; otherwise one line naming the field, its value and the constraint.
  std::optional<std::string> validate() const;
};

enum class InterpenetrationStatus {
  kNoContact,      ///< no boundary vertex of either mesh was inside the other: nothing moved
  kSeparated,      ///< penetrations were removed: no boundary vertex is inside the other mesh
  kMaxIterations,  ///< rounds exhausted with vertices still inside (meshes hold the last state)
  kSolverFailed,   ///< a Newton round failed (not positive definite, non-finite, no step); the
                   ///< meshes hold the last accepted state, with no inverted tet
  kInvalidInput,   ///< invalid options or meshes: nothing was changed (see message)
};

const char* to_string(InterpenetrationStatus status);

struct InterpenetrationSummary {
  InterpenetrationStatus status = InterpenetrationStatus::kInvalidInput;
  /// Boundary vertices of A inside B and of B inside A, before and after.
  Eigen::Index penetrating_a_before = 0;
  Eigen::Index penetrating_b_before = 0;
  Eigen::Index penetrating_a_after = 0;
  Eigen::Index penetrating_b_after = 0;
  /// Largest depth of a penetrating vertex (distance to the other boundary), mesh units.
  double max_depth_before = 0.0;
  double max_depth_after = 0.0;
  /// Tets in the active region of each mesh (union over the rounds) and the free vertices.
  Eigen::Index active_tets_a = 0;
  Eigen::Index active_tets_b = 0;
  Eigen::Index free_vertices = 0;
  /// Vertices of A and B whose position changed, and the largest displacement (mesh units).
  Eigen::Index vertices_moved = 0;
  double max_displacement = 0.0;
  /// Contact rounds (detection + solve) and Newton iterations over all rounds.
  int iterations = 0;
  int newton_iterations = 0;
  /// The mean edge length h of the two meshes and the margin left (mesh units).
  double mean_edge_length = 0.0;
  double margin = 0.0;
  double seconds = 0.0;            ///< wall-clock time
  double detection_seconds = 0.0;  ///< of which collision detection
  std::string message;             ///< one line: what happened (or why the input is invalid)

  bool converged() const {
    return status == InterpenetrationStatus::kNoContact ||
           status == InterpenetrationStatus::kSeparated;
  }
  /// One line: status, penetrations before → after, depth, region, displacement, time.
  std::string brief_report() const;
};

/// Boundary vertices of `mesh` inside the volume of `other` (tolerance 1e-10 in barycentric
/// coordinates, so a vertex on the other's boundary counts), with their depths (mesh units).
struct Penetrations {
  Eigen::VectorXi vertices;  ///< indices into mesh.vertices, increasing
  Eigen::VectorXd depths;    ///< distance to other's boundary surface, same order
  double max_depth() const { return depths.size() > 0 ? depths.maxCoeff() : 0.0; }
};

/// The collision test of step 1, also usable on its own (tests, reports). std::nullopt when a
/// mesh is invalid (empty, index out of range, non-manifold).
std::optional<Penetrations> find_penetrations(const TetMesh& mesh, const TetMesh& other);

/// Moves the active regions of a and b (in place) until no boundary vertex of either is inside
/// the other. Meshes: #V by 3 positions (any length unit), right-handed tets. Vertices outside the
/// active regions keep their positions bit for bit. kInvalidInput leaves both meshes unchanged.
InterpenetrationSummary remove_interpenetration(TetMesh& a, TetMesh& b,
                                                const InterpenetrationOptions& options = {});

}  // namespace sinew::offline
