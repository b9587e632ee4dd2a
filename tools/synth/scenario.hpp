#pragma once
/// The physics behind sinew-synth: a plane beam in pixel units, loaded frame by frame and solved
/// with the project's own StaticBeamSolver on a mesh four times finer than the tracker's, so that
/// the rendered object is (to within the fine mesh) the true continuous shape. Also the camera's
/// homographies. Everything here is deterministic; the only randomness is in the renderer.
///
/// Coordinates are pixels of the reference (first) frame, x right, y down, with pixel centres at
/// integers ((0, 0) is the centre of the top-left pixel). Rotations are positive from +x towards
/// +y.

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/beam/beam_model.hpp"

namespace sinew::tools::synth {

enum class Scenario {
  kCantilever,  ///< straight beam clamped at node 0, dead tip load ramping from λ = 0 to λ_max
  kFreeCurved,  ///< curved free beam (a whisker) under a self-equilibrated three-point load set
};
enum class Thickness { kThick, kThin };
enum class CameraMotion { kNone, kPanRotate };

/// Frames first .. first + count − 1.
struct FrameRange {
  int first = 0;
  int count = 0;
  bool contains(int frame) const { return frame >= first && frame < first + count; }
};

/// Every input of a synthetic sequence (the command line, already validated).
struct SynthOptions {
  Scenario scenario = Scenario::kCantilever;
  int frames = 40;   ///< ≥ 2
  int width = 1024;  ///< image size, pixels
  int height = 768;
  int elements = 16;  ///< tracker elements; the simulation uses 4× as many
  Thickness thickness = Thickness::kThick;
  double half_width_px = 6.0;  ///< half the drawn width of the beam; the section height is 2×
  double lambda_max = 5.0;     ///< largest λ = P·L²/EI of the sequence, ≥ 0
  double noise = 8.0;          ///< σ of the additive Gaussian noise, grey levels
  int clutter = 12;            ///< number of clutter line segments
  std::optional<FrameRange> occluder;
  std::optional<FrameRange> vanish;
  CameraMotion camera_motion = CameraMotion::kNone;
  std::uint64_t seed = 1;
};

/// Fine simulation elements per tracker element: tracker node k is fine node kSubdivision·k.
inline constexpr int kSubdivision = 4;

/// The beam as the tracker should be told about it (init.json).
struct TrackerBeam {
  Eigen::Matrix2Xd rest_positions;  ///< 2 x (n + 1) tracker nodes on the first frame, pixels
  common::BeamMaterial material;    ///< pixel units
  bool clamped_base = false;        ///< node 0 clamped (cantilever)
  std::vector<int> load_nodes;  ///< tracker nodes where loads act, when the tracker may assume it
};

/// The true state of one frame.
struct FrameTruth {
  double lambda = 0.0;          ///< P·L²/EI (P: tip load, or the middle force of free_curved)
  Eigen::Matrix2Xd centreline;  ///< 2 x (4n + 1) fine nodes, reference-frame pixels
  Eigen::Matrix3Xd nodes;       ///< 3 x (n + 1): x, y (pixels) and θ (rad, relative to frame 0)
  Eigen::Matrix3Xd loads;       ///< 3 x (n + 1): fx, fy (force units), m (force·pixel)
  int solver_iterations = 0;    ///< Newton iterations spent on this frame
};

struct Simulation {
  TrackerBeam beam;
  double length = 0.0;  ///< reference length L of the beam, pixels
  std::vector<FrameTruth> frames;
};

/// Runs the scenario. Throws std::runtime_error (one line) when the solver does not converge.
Simulation simulate(const SynthOptions& options);

/// The camera's map from reference-frame pixels to frame `frame`'s pixels (identity on frame 0 and
/// without camera motion), normalised so that H(2, 2) = 1.
Eigen::Matrix3d camera_homography(const SynthOptions& options, int frame);

/// Empty when every frame's beam (as seen by the camera) lies inside the image with a margin of
/// half_width + 4 pixels; otherwise one line naming the options, the frame and the point.
std::optional<std::string> check_beam_inside_image(const SynthOptions& options,
                                                   const Simulation& simulation);

}  // namespace sinew::tools::synth
