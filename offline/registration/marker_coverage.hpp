#pragma once
/// Where the data pins a registration result along the surface's normal, and where only the
/// smoothness term shapes it.
///
/// A landmark or an attachment fixes a material point: the surface near it is pinned in every
/// direction. An ICP marker fixes only the surface's distance to it: the surface is pinned along
/// its normal there and may slide under the marker. So a part of the surface can be close to many
/// markers and still be free in one direction, e.g. the free end of a bar whose markers all lie
/// on its sides: nothing holds the end's position along the bar.
///
/// A surface that slides along itself keeps its shape, so what decides the shape is how firmly
/// the data holds each part of the surface along its own normal. For each surface vertex p this
/// measures:
///  - distance: to the nearest data point;
///  - pinning: n_pᵀ M(p) n_p, with M(p) = Σ_i w_i(p) P_i, w_i = exp(−|p − z_i|²/2h²), P_i = I for a
///    landmark or attachment and n_i n_iᵀ for an ICP marker; n_p and n_i are the surface's unit
///    normals at p and at the surface vertex nearest to z_i (area-weighted vertex normals).
/// The yardstick h is the nominal spacing sqrt(area / markers): the spacing the stage's markers
/// would have if spread evenly over the surface. One landmark k spacings away pins with
/// exp(−k²/2); a vertex is "weakly pinned" when its pinning is below that for
/// k = uncovered_spacings, and "uncovered" when it is farther than k spacings from every data
/// point. For landmarks scattered uniformly at random, the area farther than k spacings from all
/// of them is about exp(−π k²): 4.3% at k = 1, 0.09% at k = 1.5.
///
/// What it catches and what not: a part of the surface with no marker facing its way (a half of a
/// box without markers: tests/tools/test_sinew_register.cpp, CoverageReportsTheHalfWithoutMarkers).
/// It is a local measure: it does not see that three markers in a line on an end face leave the
/// face free to tilt about that line, nor a local minimum of the registration. On the ICP ground
/// truth of docs/registration.md ("Which markers are drawn decides it") every draw is fully
/// covered and pinned by this measure, including the draws that end 2.4% and 4.9% off.

#include <Eigen/Core>
#include <vector>

namespace sinew::offline {

struct MarkerCoverageOptions {
  /// The distance, in nominal spacings, that defines "uncovered" and "weakly pinned".
  double uncovered_spacings = 1.5;
};

struct MarkerCoverage {
  Eigen::VectorXd distance;        ///< per vertex: to the nearest data point (+∞ without points)
  Eigen::VectorXd pinning;         ///< per vertex: n_pᵀ M(p) n_p (0 without points or normal)
  double area = 0.0;               ///< of the surface
  double nominal_spacing = 0.0;    ///< sqrt(area / markers)
  double pinning_threshold = 0.0;  ///< exp(−k²/2), k = uncovered_spacings
  double max_distance = 0.0;       ///< max of distance over the surface's vertices
  Eigen::Index farthest_vertex = -1;
  double min_pinning = 0.0;  ///< min of pinning over the surface's vertices
  Eigen::Index weakest_vertex = -1;
  /// Fractions of the surface's area (each vertex carries a third of its triangles' areas) at
  /// vertices farther than uncovered_spacings nominal spacings from every data point, and at
  /// vertices whose pinning is below pinning_threshold.
  double uncovered_area_fraction = 0.0;
  double weakly_pinned_area_fraction = 0.0;
};

/// vertices: #V by 3 positions; triangles: #F by 3 vertex indices (in range), the surface;
/// pinned: landmark and attachment targets; sliding: ICP markers; markers: how many data points
/// count for the nominal spacing (the stage's markers, without the attachments' many targets;
/// 0: all of them). Vertices of no triangle (a tet mesh's interior ones, say) get a distance (and
/// pinning 0) but are left out of the extremes and fractions, so a tet mesh and its boundary
/// triangles can be passed as they are.
MarkerCoverage marker_coverage(const Eigen::MatrixXd& vertices, const Eigen::MatrixXi& triangles,
                               const std::vector<Eigen::Vector3d>& pinned,
                               const std::vector<Eigen::Vector3d>& sliding, std::size_t markers = 0,
                               const MarkerCoverageOptions& options = {});

}  // namespace sinew::offline
