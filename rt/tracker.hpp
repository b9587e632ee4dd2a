#pragma once
/// The real-time beam tracker (seed 000 §4): per frame, predict the state from the previous two
/// frames, search for image observations along the normals of the model's Hermite centreline, and
/// take Tukey-weighted Newton steps (K_T + ∇FᵀW∇F) du = −(∇FᵀW F + p(u) − p(u_r)) (eq. 10),
/// repeating whole minimisations until the model stops moving. Each repetition r measures elastic
/// forces relative to its own start u_r, so the image forces can pull the model all the way onto
/// the data while the beam keeps each step physically plausible; the total displacement u_T is the
/// sum. Then the applied nodal loads f = p(u_T) (the seed's −p sign for the reaction) are recovered
/// and verified by a forward static solve, and, when load nodes are named, the loads at those nodes
/// only are fitted so that the equilibrium shape matches the tracked one (a well-posed estimate).
///
/// Real-time contract: all memory is sized at construction; track() never allocates, throws or
/// prints, and its work is bounded by max_repetitions x max_newton_iterations.

#include <Eigen/Core>
#include <Eigen/Dense>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "common/beam/beam_model.hpp"
#include "common/beam/block_tridiagonal.hpp"
#include "common/beam/static_solver.hpp"
#include "rt/centreline.hpp"
#include "rt/load_fit.hpp"
#include "rt/observation.hpp"

namespace sinew::rt {

/// Which deformation model regularises the fit.
enum class TrackerModel {
  kBeam,   ///< the nonlinear Timoshenko beam (the seed's method)
  kSnake,  ///< the seed's §5.2 baseline: stretching + bending weights on a polyline
};

/// What a free first node's end search along the tangent looks for (see observe_ends).
enum class StartEnd {
  kObjectEnd,   ///< where the object gives way to background (any free end)
  kDarkRegion,  ///< where a dark region begins: a whisker's follicle on the face, which may slide
                ///< along the face's edge and move with it, but not along the whisker into the fur
};

struct TrackerOptions {
  TrackerModel model = TrackerModel::kBeam;
  ObservationMode observation = ObservationMode::kEdge;
  /// kEdge: half the object's width in pixels (its boundaries sit at ±half_width_px), > 0.
  double half_width_px = 0.0;
  /// kEdge: intensity step polarity; kAuto (default) measures it on the first frame.
  EdgePolarity polarity = EdgePolarity::kAuto;
  /// Sample points per element (each gives one search line, two in edge mode), ≥ 1.
  int samples_per_element = 8;
  /// Search ±range pixels along the normal around the model, ≥ 1: in the repetitions after a wide
  /// first search (which caught the large motion), and in the first when the motion is predictable
  /// (see predictable_px). Costs linearly (docs/tracker.md, "Defaults").
  int search_range_px = 8;
  /// Search range of each frame's first repetition, pixels, ≥ search_range_px: catches the large
  /// motion of the first frames (no velocity yet) and of sudden accelerations; later repetitions
  /// search ±search_range_px around the updated model.
  int first_search_range_px = 40;
  /// The wide first search (±first_search_range_px, strongest candidate) costs twice a narrow one
  /// and is only needed when the motion may have outrun the constant-velocity prediction: it runs
  /// when there is no velocity yet (second frame, after a lost frame or reset_motion), when the
  /// previous frame's prediction missed by more than this (pixels, max over nodes), and as a retry
  /// when a narrow first repetition leaves fewer than half of the search lines on the object.
  /// Otherwise the first repetition searches ±search_range_px, twice this. ≥ 0; 0 always
  /// searches wide. Edge mode only: a thin line in clutter needs the wide search's strongest-
  /// candidate association on every frame (measured: free curved beam 0.34 → 0.57 px without).
  double predictable_px = 4.0;
  /// Strongest responses kept per search line; the one nearest the model is used, ≥ 1.
  int max_candidates = 3;
  /// Weakest response accepted: grey levels per pixel (edges) or grey levels (lines), > 0.
  double min_strength = 8.0;
  /// Line modes: distance of the surround samples; 0 picks round(line half-width + 1.5) = 3 px.
  int line_surround_px = 0;
  /// Profile averaged over ±band_px pixels along the tangent (noise ÷ √(2·band + 1)), ≥ 0.
  int band_px = 1;
  /// End search lines (along the tangent, observe_ends) average over at most ±end_band_px pixels
  /// across the object, [0, 10]: across a thin object a wide band averages the background into the
  /// step where it ends (a whisker's fall into the face), so it is set apart from band_px.
  int end_band_px = 1;
  /// Image term weight relative to the elements' bending stiffness 12·EI/ℓ³ (ℓ below), > 0. Higher
  /// fits in fewer repetitions; lower regularises more per repetition.
  double image_stiffness = 1.0;
  /// Shortest length ℓ the image term is scaled to, pixels, ≥ 0; 0 picks 4·half_width_px (twice the
  /// object's width). Elements at least this long weigh each search line by
  /// image_stiffness·12·EI/L₀³ per element; shorter ones keep the image term's weight per unit
  /// length at that of ℓ (12·EI/ℓ⁴), where L₀⁻³ would make it grow as the fourth power of the
  /// number of elements while the beam's axial stiffness grows only linearly: the image then
  /// stretches the beam along itself, where edges carry no information.
  double min_image_length_px = 0.0;
  /// Fraction β of the bending force measured from the reference rather than from the start of
  /// each repetition, [0, 1). 0 is the seed's scheme (the shape follows the data with no memory of
  /// the reference); a little memory removes kinks that clutter or an occluder left behind, at a
  /// negligible bias on the smooth bending modes (their stiffness is ~1e-4 of the image term's).
  double bending_memory = 0.5;
  /// Repeated minimisations per frame (bound), ≥ 1.
  int max_repetitions = 12;
  /// Newton iterations per minimisation (bound), ≥ 1.
  int max_newton_iterations = 3;
  /// A frame has converged when a repetition moves the nodes by less than this (RMS), pixels, > 0.
  double convergence_px = 0.02;
  /// A repetition searches the image again only if the model moved more than this (pixels, max
  /// over nodes) since the last search; otherwise it re-uses the candidates. 0 always searches.
  /// A wide search's one-row candidates are always replaced by a narrow search.
  double research_px = 3.0;
  /// Tukey's constant in units of the robust residual scale, > 0. 4.685 is the textbook 95 %
  /// efficiency; 3.5 rejects clutter crossings earlier.
  double tukey_c = 3.5;
  /// Floor of the robust residual scale (1.4826·median|d|), pixels, > 0.
  double min_sigma_px = 0.25;
  /// Below this fraction of search lines with an inlier the frame is reported lost, [0, 1].
  double min_inlier_fraction = 0.25;
  /// Also search along the tangent for the object's end at each free end (a node with no fixed
  /// translation): without it a free beam can slide along itself, which normals cannot see.
  bool observe_ends = true;
  /// kDarkRidge: no ridge is seen where the brighter side is darker than this, grey levels, ≥ 0
  /// (e.g. a third of the backlight, so that fur and dark objects give no observations).
  double ridge_min_background = 0.0;
  /// What the first node's end search looks for; kDarkRegion for objects that grow out of a
  /// dark region (whiskers from the face). In kDarkRidge mode the free last node (a whisker's
  /// tip, whose contrast fades to nothing) is not observed along the tangent: the beam's axial
  /// stiffness keeps its length.
  StartEnd start_end = StartEnd::kObjectEnd;
  /// kDarkRegion: no search line along a normal within this arc length of the first node,
  /// pixels, ≥ 0. Next to the dark region its soft edge darkens one side of a line's profile
  /// where the object leaves it obliquely, and the ridge found there moves sideways with the
  /// angle between them: the base's tangent turns more or less than the object (rendered whiskers
  /// turning rigidly about their follicles: 0.89 and 1.05–1.09 of the true turn; with 6 px
  /// 1.006 and 0.99–1.04). The first node is still held along the object by its end search and
  /// sideways by the lines beyond.
  double start_clearance_px = 0.0;
  /// kDarkRegion with kDarkRidge: within this arc length of the first node, pixels, ≥ 0, a ridge's
  /// depth is measured below the mean of its two sides (bounded by 4× the depth below the darker
  /// side, so that an edge still answers little) instead of below the darker side. Next to the
  /// dark region the background along a line is curved (the region's soft edge), which moves the
  /// peak of the darker side's depth sideways; the mean of both sides leaves a linear or
  /// quadratic background's peak in place.
  double start_mean_surround_px = 0.0;
  /// kDarkRidge: each search line's sub-pixel position from the profile's own darkness instead of
  /// the ridge response (lines within start_mean_surround_px keep the response's, which the
  /// face's edge does not move). The response's side samples, 3 px out, add their noise to the
  /// position: on the rendered sliding pole (σ 4) the tracked curve is 0.063 px from the truth
  /// instead of 0.098. Off by default: with the darker-side depth next to the follicle the
  /// darkness there is pulled by the face's edge (docs/tracker.md, "What the images allow").
  bool ridge_position_from_profile = false;
  /// Weight of an end search line relative to a search line along a normal, > 0. A free beam is
  /// held along itself by its end observations alone, against the whole length's normal lines.
  double end_weight = 1.0;
  /// kDarkRegion: weakest intensity step accepted as the dark region's edge, grey levels per
  /// pixel, > 0.
  double dark_region_min_step = 10.0;
  /// An inlier counts as the object only if its response reaches this fraction of the object's
  /// typical response (running median over good frames), [0, 1); below min_inlier_fraction such
  /// lines the frame is lost (the object left, or is hidden).
  double min_relative_strength = 0.4;
  /// ... and lies within this distance of the fitted model, pixels, > 0.
  double object_residual_px = 1.5;
  /// Solve each Newton step as a dense system (the seed's O(n³) solve) instead of
  /// block-tridiagonal; for comparisons only.
  bool dense_solve = false;
  /// Predict from the last two frames (constant velocity); otherwise start from the last frame.
  bool predict = true;
  /// Verify the recovered per-node forces by a forward static solve (seed 000 §4).
  bool verify_forces = true;
  /// Load increments of a verification solve started from the reference configuration, ≥ 1.
  int verify_load_steps = 24;
  /// Snake baseline weights (seed 000 §5.2): stretching and bending, relative to the image term.
  double snake_stretch_weight = 1000.0;
  double snake_bend_weight = 1000.0;
  /// Load fit (when load nodes are given): Gauss–Newton iterations per frame, ≥ 1.
  int max_load_fit_iterations = 6;
  /// Load fit: also fit a moment at each load node. Off by default: a contact (a whisker touching
  /// a pole, a pushed tip) transmits a force, and a free moment trades off against the force.
  bool fit_moments = false;
  /// Load fit (rt/load_fit.hpp): sub-elements per element of the beam the loads are fitted on
  /// (its O(h²) error would otherwise read as a load error of a few per cent), ≥ 1.
  int load_fit_subdivisions = 4;
  /// Load fit: solve the loads and the equilibrium together, one factorisation per iteration
  /// (up to 2 max_load_fit_iterations), before the nested fit (an equilibrium solved to 1e-9
  /// inside every iteration), which remains the fallback. Same loads at convergence.
  bool coupled_load_fit = true;

  /// Empty when valid; otherwise one line naming the field, its value and the constraint.
  std::optional<std::string> validate() const;
};

enum class FrameStatus { kOk, kLost, kNotConverged };
const char* to_string(FrameStatus status);

/// Plain data about one tracked frame.
struct FrameSummary {
  FrameStatus status = FrameStatus::kLost;
  int repetitions = 0;   ///< minimisations run
  int iterations = 0;    ///< Newton iterations over all repetitions
  int searches = 0;      ///< repetitions that searched the image (others re-used candidates)
  int predicted = 0;     ///< 1 when the last repetition's move was predicted, not iterated
  int search_lines = 0;  ///< search lines inside the image
  double rms_px = 0.0;   ///< RMS image residual of the inliers at the end, pixels
  double inlier_fraction = 0.0;  ///< search lines with an inlier observation / all search lines
  double object_fraction = 0.0;  ///< inliers with an object-like response / all search lines
  bool verified = false;         ///< a verification solve ran and converged
  double verify_px = 0.0;        ///< largest node distance between the verification and the fit
  bool loads_fitted = false;     ///< the load-node fit ran and converged
  double load_fit_rms_px = 0.0;  ///< RMS node distance between the fitted equilibrium and the fit
  double seconds = 0.0;          ///< wall time of track()
  double search_seconds = 0.0;   ///< of which searching the image along the normals
};

class Tracker {
 public:
  /// beam: the reference configuration is the polyline on the first frame (pixels). load_nodes:
  /// nodes where loads are fitted (needs fixed dofs that constrain rigid motion). Check valid().
  Tracker(common::BeamDescription beam, TrackerOptions options, std::vector<int> load_nodes = {});

  bool valid() const { return error_.empty(); }
  const std::string& error() const { return error_; }
  const common::BeamModel& model() const { return model_; }
  const TrackerOptions& options() const { return options_; }
  int num_nodes() const { return model_.num_nodes(); }

  /// Tracks one frame. Never allocates, throws or prints.
  FrameSummary track(const ImageView& frame) noexcept;

  /// Forgets the motion history: the next frame starts from the last state without velocity.
  void reset_motion() noexcept;

  /// Starts again from the node positions `nodes` (2 x num_nodes(), pixels; e.g. the object found
  /// again by a detector): translations from them, rotations from their polyline's tangents
  /// against the reference's, no velocity, and the next frame searches as after a lost frame.
  /// Outside the per-frame contract only in that the caller decides when; no allocation.
  /// narrow: the nodes lie on the object in the frame the next track() call gets (a detection of
  /// that frame): its first repetition searches ±search_range_px for the nearest candidates
  /// instead of twice first_search_range_px for the strongest (which, beside a darker neighbour,
  /// is the neighbour's).
  void restart_at(const Eigen::Ref<const Eigen::Matrix2Xd>& nodes, bool narrow = false) noexcept;

  /// Discards the last frame's fit (a caller found it on another object: a neighbouring whisker,
  /// a pole): the state returns to the frame before, and the next frame searches as after a lost
  /// frame. No effect when the last frame was already lost. No allocation.
  void reject_last_frame() noexcept;

  /// Candidates at points `exclusion` vetoes are dropped from every later search along the
  /// normals (not the end searches along the tangent, nor kEdgeMap's) until it is set again;
  /// nullptr (the default) drops none. The object must outlive its use. No allocation.
  void set_exclusion(const CandidateExclusion* exclusion) noexcept { exclusion_ = exclusion; }

  /// The running median response of the object's inlier observations (the search's units, see
  /// Candidate::strength): how strongly the image shows the object.
  double typical_strength() const { return typical_strength_; }

  /// State u = [ux, uy, θ] per node relative to the reference (first-frame) polyline.
  const Eigen::VectorXd& state() const { return u_; }
  /// Current node position (pixels).
  Eigen::Vector2d node_position(int i) const {
    return model_.rest_positions().col(i) + u_.segment<2>(3 * i);
  }
  /// Per-node applied loads f = p(u_T) [fx, fy, m] (the seed's forces, sign: load on the beam).
  const Eigen::VectorXd& forces() const { return forces_; }
  /// Loads fitted at the load nodes (zeros elsewhere); zero when no load nodes were given.
  const Eigen::VectorXd& fitted_loads() const { return fitted_loads_; }
  const std::vector<int>& load_nodes() const { return load_nodes_; }
  /// The model curve of an element at the current state: the Hermite centreline (beam) or the
  /// straight chord (snake), at ξ ∈ [0, 1]. For overlays; no allocation.
  CentrelinePoint centreline(int element, double xi) const;
  /// Node positions of the verification solve (valid when the summary says verified).
  const Eigen::VectorXd& verification_state() const { return u_verify_; }

 private:
  static constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();  // a line with no residual
  struct SearchLine {
    int element = 0;
    float xi = 0.0f;
    float side = 0.0f;  // −1, +1 (edge boundaries) or 0 (line centre)
    int end = 0;        // ±1: searches along the outward tangent for the object's end (free ends)
    int point = 0;      // index into sample_points_ (both boundaries of a sample share a point)
    bool mean_surround = false;  // kDarkRidge depth from both sides' mean (start_mean_surround_px)
    Eigen::Vector2d centre = Eigen::Vector2d::Zero();
    Eigen::Vector2d normal = Eigen::Vector2d::Zero();
    int num_candidates = 0;
  };

  // A point of the model curve that search lines are placed at.
  struct SamplePoint {
    int element = 0;
    double xi = 0.0;
    HermiteBasis basis;  // hermite_basis(xi), evaluated once
  };

  // The model curve at a sample point: what the search reads (position, normal) and what a Newton
  // step reads (position, ∂c/∂u_e = [h00·I, dc_dtheta1, h01·I, dc_dtheta2] of its element).
  struct ModelPoint {
    Eigen::Vector2d position = Eigen::Vector2d::Zero();
    Eigen::Vector2d normal = Eigen::Vector2d::Zero();
    Eigen::Vector2d dc_dtheta1 = Eigen::Vector2d::Zero();
    Eigen::Vector2d dc_dtheta2 = Eigen::Vector2d::Zero();
    double h00 = 0.0, h01 = 0.0;
  };

  // No velocity, no verification warm start, a wide search next (restart_at, reject_last_frame).
  void continue_as_after_a_lost_frame() noexcept;
  // points_ = the model curve at every sample point at u_: each element's rotations are evaluated
  // once (not once per search line), and the two boundaries of a sample share their point.
  // Positions always; normals (the search, and a Newton step's expected points off the curve)
  // and the Jacobians' parts (a Newton step) when asked.
  void evaluate_points(bool normals, bool jacobians);
  // Whether points_ holds what evaluate_points(normals, jacobians) would write now: it was
  // evaluated with them at the very same state (a search's points serve the Newton step after it).
  bool points_current(bool normals, bool jacobians) const;
  // Where the line expects the image feature at u_, and the direction it searches along.
  Eigen::Vector2d expected_point(const SearchLine& line, const ModelPoint& p,
                                 Eigen::Vector2d* direction) const;
  void search(const ImageView& frame, int range_px);
  // kAuto: compares the intensity on the centreline with that at ±(half width + 3 px) along the
  // initial polyline; returns kAny when the contrast is too weak to tell.
  EdgePolarity measure_polarity(const ImageView& frame) const;
  // Residuals of all search lines at u_ (nearest candidate) and their Jacobian rows; returns the
  // robust Tukey cut-off tukey_c · max(1.4826·median|d|, min_sigma_px) (also kept in cutoff_).
  double residuals();
  // Fraction of search lines whose residual at the last Newton step looks like the object.
  double object_fraction_at_last_step() const;
  // Adds the Tukey-weighted image term (Gauss–Newton) to the system and gradient_.
  void add_image_term(double cutoff);
  // Adds the snake energy's gradient and (PSD) Hessian at u_ to gradient_ and snake_matrix_.
  void add_snake_term();
  // p_ref_ = the model's elastic force at u_ (start of a repetition).
  void internal_force_at_start();
  // The bending reference force at u_ (what internal_force_at_start puts in p_ref_) into p_ref.
  void bending_reference_force(Eigen::VectorXd& p_ref) const;
  bool newton_step();
  // track() in its steps: the predicted start (true when it carries a velocity); the repetitions
  // of search and Newton fit (true when they converged; *failed when a Newton step failed), of
  // which a last one may be predicted instead of taken (take_predicted_repetition: true when its
  // move was applied); the final residuals with the inlier and object fractions (returns how many
  // inlier strengths sorted_ holds for the running typical strength).
  bool predict(const ImageView& frame) noexcept;
  bool repetitions(const ImageView& frame, FrameSummary& summary, bool* failed) noexcept;
  bool take_predicted_repetition(double step, bool coarse_candidates) noexcept;
  int measure_fit(const ImageView& frame, FrameSummary& summary, bool converged,
                  bool failed) noexcept;
  double max_node_distance(const Eigen::VectorXd& a, const Eigen::VectorXd& b) const;
  // The largest node translation of a step du (pixels).
  double max_node_translation(const Eigen::VectorXd& du) const;
  double rms_node_distance(const Eigen::VectorXd& a, const Eigen::VectorXd& b) const;
  void verify(FrameSummary& summary);
  void fit_loads(FrameSummary& summary);

  common::BeamModel model_;
  TrackerOptions options_;
  std::vector<int> load_nodes_;
  std::string error_;
  ProfileSearch profile_search_;
  int sides_ = 1;
  double observation_weight_ = 0.0;
  double damping_translation_ = 0.0, damping_rotation_ = 0.0;
  int frames_ = 0;
  bool strongest_candidate_ = false;  // associate with the strongest candidate (first repetition)
  EdgePolarity polarity_ = EdgePolarity::kAny;     // resolved polarity (kAuto decided on frame 0)
  const CandidateExclusion* exclusion_ = nullptr;  // see set_exclusion()

  // Per-frame workspace, sized at construction.
  std::vector<SearchLine> lines_;
  std::vector<SamplePoint> sample_points_;
  std::vector<ModelPoint> points_;  // the model curve at sample_points_ (evaluate_points)
  // The state points_ was evaluated at, and with which parts (points_current).
  Eigen::VectorXd u_points_;
  bool points_normals_ = false, points_jacobians_ = false;
  std::vector<Candidate> candidates_;  // lines_.size() x max_candidates
  std::vector<float> residual_;        // per line, NaN when it has no candidate
  std::vector<float> strength_;        // response of the candidate each line uses
  double typical_strength_ = 0.0;      // running median response of the object's inliers
  bool previous_lost_ = false;
  bool narrow_next_ = false;    // restart_at(..., narrow): the next frame's first search is narrow
  bool last_accepted_ = false;  // the last frame's fit was taken (ok or not converged)
  double last_miss_px_ = std::numeric_limits<double>::infinity();  // prediction error, last frame
  double cutoff_ = 0.0;                                            // robust cutoff of the last step
  std::vector<float> sorted_;                                      // scratch for the median
  std::vector<float> scratch_;
  std::vector<common::Vector6d> jacobian_rows_;  // ∂d/∂u_e per line
  Eigen::Matrix2Xd node_tangents_;               // unit reference tangent per node
  Eigen::VectorXd u_searched_;                   // state at the last search
  Eigen::VectorXd u_, u_prev1_, u_prev2_, u_predicted_, u_start_, p_ref_, p_next_, gradient_, du_,
      forces_;
  Eigen::VectorXd fitted_loads_;
  common::BlockTridiagonal tangent_;
  common::BlockTridiagonalLdlt ldlt_;
  // Snake baseline: dense system (its bending term couples nodes i−1 and i+1).
  Eigen::MatrixXd dense_tangent_;  // dense_solve only
  Eigen::LDLT<Eigen::MatrixXd> dense_ldlt_;
  Eigen::MatrixXd snake_matrix_;
  Eigen::LDLT<Eigen::MatrixXd> snake_ldlt_;
  std::vector<unsigned char> snake_fixed_;

  // Verification.
  common::BeamModel verify_model_;
  common::StaticBeamSolver verify_solver_;
  common::StaticBeamSolver verify_solver_warm_;
  common::StaticBeamSolver verify_solver_direct_;
  Eigen::VectorXd u_verify_, verify_loads_prev_;
  Eigen::VectorXd verify_previous_state_, verify_previous_forces_;  // last tracked frame
  Eigen::VectorXd verify_backup_;
  bool verify_have_previous_ = false;

  // Load fit, on the beam with every element subdivided.
  // The load fit at the load nodes (rt/load_fit.hpp), when there are any; its load points are
  // the load nodes on its subdivided beam.
  std::optional<LoadFit> load_fit_;
  std::vector<int> fit_points_;
};

}  // namespace sinew::rt
